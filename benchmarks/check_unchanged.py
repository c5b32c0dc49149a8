"""Snapshot the README examples and a quick-profile run; compare two snapshots.

For changes that must leave behaviour and numbers unchanged (a restructuring): take a snapshot
before, one after, and compare them.

    export PYTHONPATH=$PWD/src        # the checkout's package (and its built C kernel)
    python benchmarks/check_unchanged.py snapshot /somewhere/before   # README examples + quick run
    ... change the code ...
    python benchmarks/check_unchanged.py snapshot /somewhere/after
    python benchmarks/check_unchanged.py compare /somewhere/before /somewhere/after [--rtol 1e-9]

``snapshot OUTDIR [--skip-readme] [--skip-quick] [--navchip-data DIR|none]``

* README part: every command of the fenced ``bash`` blocks of ``README.md`` and every ``python``
  block (run with ``MPLBACKEND=Agg``), in order, in scratch directories outside the repository
  (``cd "$(mktemp -d)"`` starts a new one), except the commands matched by ``SKIP_RULES``
  (installation, the test suite, the pipeline; the manifest lists what was run and skipped, and
  why). Kept: stdout, stderr, exit status (``bash -o pipefail``), every file the commands write,
  and the output the README shows after the command (an untyped fenced block).
* Quick part: ``snakemake -j2 --configfile config/quick.yaml`` in a temporary git repository
  holding the checkout's tracked files except ``src/`` (the package comes from ``PYTHONPATH``, as
  in ``tests/conftest.py``); kept: exit status, the "N of M steps" line, every file under
  ``results/quick/``. The Navchip data directory (``--navchip-data``; default: the dataset
  registry's local copy when it exists) is passed as a second config file, so that a checkout
  whose ``../shared/data`` is missing still runs the Navchip rules.
* Files are stored normalised, as JSON: tables (CSV/TSV) cell by cell, JSON/YAML as trees,
  ``.npy``/HDF5/NetCDF as arrays (large ones as statistics + sha256), Markdown/text/HTML as lines,
  figures only as existence and size (pixels; PDF/SVG: page size). OUTDIR gets ``manifest.json``,
  ``readme.json``, ``quick.json``.

``compare BEFORE AFTER [--rtol R]`` prints every difference (file, key or line, before, after)
and exits 1 if there is one, 0 otherwise. Integers compare exactly, floats with relative tolerance
R (default 1e-9). Text is compared after the masks of ``MASKS`` (dates, absolute paths,
commit-like hex strings, elapsed times) and with its numbers compared as numbers; table columns
and tree keys named by ``TIMING_KEYS`` and files matched by ``EXCLUDE_RULES`` are not compared
(nondeterministic: timings, Snakemake's own logs and metadata). Masks are applied at compare time,
so an old snapshot is re-judged with the current rules.

Neither subcommand writes into the repository (checked: ``git status`` before and after a
snapshot is recorded in the manifest).
"""

from __future__ import annotations

import argparse
import csv
import difflib
import fnmatch
import hashlib
import io
import json
import math
import os
import platform
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCHEMA = 1
QUICK_ARGS = ("-j2", "--configfile", "config/quick.yaml")  # the README's command
QUICK_OUT = "results/quick"  # config/quick.yaml: outdir
#: largest array / table stored value by value; larger ones are stored as statistics + sha256
MAX_VALUES = 20_000

# --------------------------------------------------------------------------------------------
# Rules (kept small and explicit: every masked or skipped thing is named here)
# --------------------------------------------------------------------------------------------

#: README commands not run: (name, regex on the command's first line, reason)
SKIP_RULES: tuple[tuple[str, str, str], ...] = (
    ("install", r"^\s*(python3?\s+-m\s+)?(pip\s+install|venv)\b",
     "makes a virtual environment or installs the package (the environment is given)"),
    ("tests", r"^\s*(python\s+-m\s+)?pytest\b", "the test suite (not an example; run on its own)"),
    ("quick-profile", r"^\s*snakemake\b.*--configfile\s+config/quick\.yaml",
     "the quick profile: run by the quick part, in a git copy of the repository"),
    ("pipeline", r"^\s*snakemake\b", "reruns the full-scale pipeline (long; writes the tracked reports/)"),
)

#: a duration: a number with a time unit ("0.043 s", "12 ms", "3 min")
DURATION = r"\b\d+(?:\.\d+)?\s?(ms|s|sec|min)\b"

#: text masks, applied in order before numbers are extracted: (name, regex, replacement); a
#: replacement None masks every duration inside the match
MASKS: tuple[tuple[str, str, str | None], ...] = (
    # embedded images (report.html): their bytes are not compared, the figure files are
    ("data-uri", r"data:[\w/+.-]+;base64,[A-Za-z0-9+/=]+", "<DATA-URI>"),
    ("date", (r"\b\d{4}-\d{2}-\d{2}(?:[T ]\d{2}:\d{2}(?::\d{2}(?:\.\d+)?)?"
              r"(?:Z|[+-]\d{2}:?\d{2}| ?UTC)?)?"), "<DATE>"),
    ("compact-date", r"\b\d{8}T\d{6}Z?", "<DATE>"),
    ("clock", r"\b\d{1,2}:\d{2}:\d{2}(?:\.\d+)?\b", "<CLOCK>"),
    ("path", r"(?<![\w.)\]])(?:/[\w.@+~-]+){2,}/?", "<PATH>"),
    # commit hashes, config hashes; not the digits of a float ("8.337367e-04", "1234567e-4")
    ("hex", r"(?<![\w.+])(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,64}(?![\w.]|[-+]\d)",
     "<HEX>"),
    # "WV 0.008 s, fit 0.043 s", "[3.713 s]", "3.75 s wall"; not "tau = 655.4 s"
    ("elapsed-after-word", r"(?i)\b(?:wv|fit|simulate|wall|cpu|took|elapsed|runtime)\s*[:=]?\s*"
                           + DURATION, None),
    ("elapsed-bracket", r"\[" + DURATION + r"\]", None),
    ("elapsed-wall", r"(?i)" + DURATION + r"\s+(?:wall|cpu)\b", None),
    # "Run time (summed job wall time): 238.5 s (fit 2 jobs 143.9 s, ...)": the whole line
    ("timing-line", r"(?i)^.*\b(?:run ?time|wall[ -]?time|cpu[ -]?time|elapsed time)\b.*$", None),
)

#: table columns (CSV/TSV/Markdown), tree keys (JSON/YAML), arrays and attributes (HDF5/NetCDF,
#: npz) holding timings, memory or ratios of timings: compared for presence only. "<name>_s" is a
#: cost in seconds except the scales and the time axis (scale_s, scales_s, time_s): results.
TIMING_KEYS = re.compile(
    r"(?i)^(seconds(_\w+)?|\w+_seconds|(?!(scales?|time)_s$)\w+_s|projected_min|speedup(_\w+)?"
    r"|cpu_time|max_rss(_mb)?|s|h:m:s|max_vms|max_uss|max_pss|io_in|io_out|mean_load"
    r"|wall(_time)?|elapsed|runtime)$")

#: files whose content is not compared (existence is, unless the rule says "drop"):
#: (name, glob on the path relative to the part's root, "exist" | "drop", reason)
EXCLUDE_RULES: tuple[tuple[str, str, str, str], ...] = (
    ("snakemake-metadata", "*.snakemake/*", "drop",
     "Snakemake's own state (hashes, locks, dated logs)"),
    ("job-logs", "*logs/*", "exist", "job logs: wall times, process ids, log timestamps"),
    ("snakemake-benchmarks", "*benchmarks/*.tsv", "exist",
     "Snakemake benchmark files: wall time, memory, I/O of each job"),
    ("pycache", "*__pycache__*", "drop", "bytecode and Numba caches"),
)

#: masks applied to file paths (archive directories are named by date and config hash)
PATH_MASKS = ("date", "compact-date", "hex")

NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w.])")
IMAGE_EXT = {".png", ".jpg", ".jpeg", ".gif", ".svg", ".pdf"}
TEXT_EXT = {".md", ".txt", ".html", ".htm", ".log", ".tex", ".rst", ""}
TABLE_EXT = {".csv": ",", ".tsv": "\t"}


# --------------------------------------------------------------------------------------------
# README commands
# --------------------------------------------------------------------------------------------

def readme_blocks(text: str) -> list[tuple[str, str]]:
    """Fenced blocks of a Markdown text as (info string, body), in order."""
    blocks, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        m = re.match(r"^(`{3,})\s*([\w+-]*)", lines[i])
        if not m:
            i += 1
            continue
        fence, info, body = m.group(1), m.group(2).lower(), []
        i += 1
        while i < len(lines) and not lines[i].startswith(fence):
            body.append(lines[i])
            i += 1
        blocks.append((info, "\n".join(body)))
        i += 1
    return blocks


def split_commands(body: str) -> list[str]:
    """Shell commands of a bash block: continuation lines joined, heredocs kept with their
    command, comment-only and blank lines dropped."""
    cmds, lines, i = [], body.splitlines(), 0
    while i < len(lines):
        line = lines[i]
        i += 1
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cmd = [line]
        while cmd[-1].rstrip().endswith("\\") and i < len(lines):
            cmd.append(lines[i])
            i += 1
        m = re.search(r"<<-?\s*['\"]?(\w+)['\"]?", cmd[0])
        if m:
            while i < len(lines):
                cmd.append(lines[i])
                i += 1
                if lines[i - 1].strip() == m.group(1):
                    break
        cmds.append("\n".join(cmd))
    return cmds


def readme_commands(readme: Path) -> list[dict[str, Any]]:
    """The README's commands in order: {"id", "command", "expected"} (expected: the untyped
    fenced block right after the command's block, i.e. the output the README shows, or None)."""
    blocks = readme_blocks(readme.read_text(encoding="utf-8"))
    out: list[dict[str, Any]] = []
    for k, (info, body) in enumerate(blocks):
        if info in ("bash", "sh", "shell", "console"):
            cmds = split_commands(body)
        elif info in ("python", "py"):
            cmds = [f"python - <<'PY'\n{body}\nPY"]
        else:
            continue
        nxt = blocks[k + 1] if k + 1 < len(blocks) else None
        expected = nxt[1] if nxt is not None and nxt[0] == "" else None
        for j, c in enumerate(cmds):
            out.append({"command": c, "expected": expected if j == len(cmds) - 1 else None})
    for n, c in enumerate(out, 1):
        c["id"] = f"{n:02d} {command_title(c['command'])}"
    return out


def command_title(cmd: str) -> str:
    """A short, stable name of a command: its first line, whitespace collapsed, 60 chars."""
    first = " ".join(cmd.splitlines()[0].replace("\\", " ").split())
    return first[:60]


def skip_reason(cmd: str) -> tuple[str, str] | None:
    """(rule name, reason) if a README command is not run, else None."""
    for name, pattern, reason in SKIP_RULES:
        if re.search(pattern, cmd.splitlines()[0]):
            return name, reason
    return None


def run_readme(scratch: Path, env: dict[str, str]) -> dict[str, Any]:
    """Run the README's commands in scratch directories; return their record and their files."""
    sessions: list[Path] = []

    def new_session() -> Path:
        d = scratch / f"session{len(sessions)}"
        d.mkdir()
        sessions.append(d)
        return d

    cwd = new_session()
    commands = []
    for c in readme_commands(REPO / "README.md"):
        rec: dict[str, Any] = {"id": c["id"], "command": c["command"], "expected": c["expected"]}
        skip = skip_reason(c["command"])
        if skip:
            rec.update(status="skipped", rule=skip[0], reason=skip[1])
        elif re.fullmatch(r"\s*(repo=\$PWD;\s*)?cd\s+\"?\$\(mktemp -d\)\"?\s*(#.*)?", c["command"]):
            cwd = new_session()
            rec.update(status="run", reason="handled by the script: a new empty scratch directory",
                       session=cwd.name, returncode=0, stdout="", stderr="")
        else:
            t0 = time.perf_counter()
            # the README's commands start in the checkout ("repo=$PWD") and then work in scratch
            proc = subprocess.run(["bash", "-o", "pipefail", "-c", c["command"]], cwd=cwd,
                                  env={**env, "repo": str(REPO)},
                                  capture_output=True, text=True, check=False)
            rec.update(status="run", session=cwd.name, returncode=proc.returncode,
                       stdout=proc.stdout, stderr=proc.stderr,
                       seconds=round(time.perf_counter() - t0, 2))
            print(f"  [{rec['seconds']:7.1f} s] exit {proc.returncode}: {c['id']}", flush=True)
        commands.append(rec)
    files = {f"{d.name}/{rel}": rep for d in sessions for rel, rep in collect_tree(d).items()}
    return {"commands": commands, "files": files}


# --------------------------------------------------------------------------------------------
# Quick profile
# --------------------------------------------------------------------------------------------

def tracked_files(repo: Path) -> list[str]:
    """Paths of the tracked files of ``repo`` (working-tree versions)."""
    out = subprocess.run(["git", "ls-files", "-z"], cwd=repo, capture_output=True, check=True)
    return [p for p in out.stdout.decode().split("\0") if p]


def git_status(repo: Path) -> str:
    return subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=repo,
                          capture_output=True, text=True, check=True).stdout


def git_copy(repo: Path, dest: Path) -> None:
    """Copy the tracked files of ``repo`` except src/ to ``dest`` and commit them there."""
    for rel in tracked_files(repo):
        if rel.startswith("src/") or not (repo / rel).is_file():
            continue
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(repo / rel, dest / rel)
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    for cmd in (["git", "init", "-q"], ["git", "add", "-A"], ["git", "commit", "-q", "-m", "copy"]):
        subprocess.run(cmd, cwd=dest, check=True, env=env, capture_output=True)


def navchip_data_dir(option: str | None, env: dict[str, str]) -> str | None:
    """The Navchip data directory to pass to the quick run (absolute), or None."""
    if option is not None:
        return None if option.lower() == "none" else str(Path(option).resolve())
    code = ("from gmwm_studies.data import local_copy, dataset_entry\n"
            "p = local_copy('navchip_wv')\n"
            "print(p.parents[len(dataset_entry('navchip_wv')['file'].split('/')) - 1]"
            " if p else '')")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=False)
    found = proc.stdout.strip()
    return found or None


def run_quick(scratch: Path, env: dict[str, str], data_dir: str | None) -> dict[str, Any]:
    """The quick profile in a git copy of the repository; its record and result files."""
    work = scratch / "repo"
    work.mkdir()
    git_copy(REPO, work)
    args = [*QUICK_ARGS]
    if data_dir is not None:
        extra = scratch / "navchip_data.yaml"
        extra.write_text(f"navchip:\n  data_dir: {json.dumps(data_dir)}\n", encoding="utf-8")
        args.append(str(extra))
    cmd = [sys.executable, "-m", "snakemake", *args]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, check=False)
    seconds = round(time.perf_counter() - t0, 1)
    log = proc.stdout + proc.stderr
    steps = re.findall(r"^\s*(\d+ of \d+ steps \(\d+%\) done)", log, flags=re.MULTILINE)
    errors = sorted(set(re.findall(r"^Error in rule (\w+):", log, flags=re.MULTILINE)))
    (scratch / "snakemake.log").write_text(log, encoding="utf-8")
    print(f"  [{seconds:7.1f} s] exit {proc.returncode}: snakemake {' '.join(args)}", flush=True)
    return {"command": "snakemake " + " ".join(args), "navchip_data_dir": data_dir,
            "returncode": proc.returncode,
            "last_steps_line": steps[-1] if steps else None, "failed_rules": errors,
            "seconds": seconds, "git_status_after": git_status(work),
            "files": collect_tree(work / QUICK_OUT)}


# --------------------------------------------------------------------------------------------
# Normalised file contents
# --------------------------------------------------------------------------------------------

def exclude_rule(rel: str) -> tuple[str, str] | None:
    for name, pattern, mode, _ in EXCLUDE_RULES:
        if fnmatch.fnmatch(rel, pattern):
            return name, mode
    return None


def collect_tree(root: Path) -> dict[str, Any]:
    """Normalised contents of every file below ``root``, by relative path."""
    out: dict[str, Any] = {}
    if not root.is_dir():
        return out
    for path in sorted(root.rglob("*")):
        if not path.is_file():
            continue
        rel = path.relative_to(root).as_posix()
        rule = exclude_rule(rel)
        if rule is not None:
            if rule[1] == "exist":
                out[rel] = {"kind": "excluded", "rule": rule[0]}
            continue
        try:
            out[rel] = normalise(path)
        except Exception as exc:  # noqa: BLE001 - an unreadable file is recorded, not fatal
            out[rel] = {"kind": "unreadable", "error": f"{type(exc).__name__}: {exc}"}
    return out


def normalise(path: Path) -> dict[str, Any]:
    """One file as JSON-able data (see the module docstring)."""
    ext = path.suffix.lower()
    if ext in IMAGE_EXT:
        return {"kind": "image", **image_size(path)}
    if ext in TABLE_EXT:
        return read_table(path, TABLE_EXT[ext])
    if ext == ".json":
        return {"kind": "tree", "data": json.loads(path.read_text(encoding="utf-8"))}
    if ext in (".yaml", ".yml"):
        import yaml

        data = yaml.safe_load(path.read_text(encoding="utf-8"))
        return {"kind": "tree", "data": json.loads(json.dumps(data, default=str))}
    if ext == ".npy":
        return {"kind": "arrays", "arrays": {"": array_record(np.load(path, allow_pickle=False))}}
    if ext == ".npz":
        with np.load(path, allow_pickle=False) as z:
            return {"kind": "arrays", "arrays": {k: array_record(z[k]) for k in sorted(z.files)}}
    if ext in (".h5", ".hdf5", ".nc", ".nc4"):
        return read_hdf5(path)
    raw = path.read_bytes()
    if ext in TEXT_EXT or is_text(raw):
        text = raw.decode("utf-8", errors="replace")
        text = apply_masks(text, ("data-uri",))  # no image bytes in the snapshot
        return {"kind": "text", "lines": text.splitlines()}
    return {"kind": "file", "bytes": len(raw), "sha256": hashlib.sha256(raw).hexdigest()}


def is_text(raw: bytes) -> bool:
    try:
        raw[:65536].decode("utf-8")
    except UnicodeDecodeError:
        return False
    return b"\0" not in raw[:65536]


def image_size(path: Path) -> dict[str, Any]:
    """Pixel size of a raster image; page size (pt) and page count of a PDF; SVG width/height."""
    ext = path.suffix.lower()
    if ext == ".png":
        with open(path, "rb") as fh:
            head = fh.read(24)
        w, h = struct.unpack(">II", head[16:24])
        return {"width": w, "height": h}
    if ext == ".pdf":
        raw = path.read_bytes()
        boxes = re.findall(rb"/MediaBox\s*\[\s*([-\d.\s]+)\]", raw)
        pages = len(re.findall(rb"/Type\s*/Page(?!s)", raw))
        return {"pages": pages, "mediabox": boxes[0].decode().split() if boxes else None}
    if ext == ".svg":
        head = path.read_text(encoding="utf-8", errors="replace")[:4000]
        m = re.search(r"<svg[^>]*", head)
        attrs = dict(re.findall(r'\b(width|height)="([^"]*)"', m.group(0))) if m else {}
        return {"width": attrs.get("width"), "height": attrs.get("height")}
    from PIL import Image

    with Image.open(path) as im:
        return {"width": im.size[0], "height": im.size[1]}


def parse_cell(s: str) -> Any:
    """A table cell: int or float when it is one number, else the string."""
    t = s.strip()
    if re.fullmatch(r"[-+]?\d+", t):
        return int(t)
    try:
        v = float(t)
    except ValueError:
        return s
    return v if re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|[-+]?(nan|inf|infinity)",
                             t, flags=re.IGNORECASE) else s


def read_table(path: Path, delimiter: str) -> dict[str, Any]:
    """A CSV/TSV table: header + cells (parsed), or per-column statistics when large."""
    text = path.read_text(encoding="utf-8")
    rows = list(csv.reader(io.StringIO(text), delimiter=delimiter))
    if not rows:
        return {"kind": "table", "columns": [], "rows": []}
    header, body = rows[0], rows[1:]
    if len(body) * max(len(header), 1) <= MAX_VALUES:
        return {"kind": "table", "columns": header, "rows": [[parse_cell(c) for c in r]
                                                             for r in body]}
    cols = {}
    for j, name in enumerate(header):
        values = [r[j] if j < len(r) else "" for r in body]
        try:
            cols[name] = array_record(np.array([float(v) for v in values]))
        except ValueError:
            cols[name] = {"strings_sha256": hashlib.sha256("\n".join(values).encode()).hexdigest(),
                          "distinct": sorted(set(values))[:50]}
    return {"kind": "table-summary", "columns": header, "n_rows": len(body), "summary": cols}


def array_record(a: np.ndarray) -> dict[str, Any]:
    """An array: shape, dtype and values, or statistics + sha256 of its bytes when large."""
    rec: dict[str, Any] = {"shape": list(a.shape), "dtype": str(a.dtype)}
    if a.dtype.kind not in "biufc":
        flat = [v.decode("utf-8", errors="replace") if isinstance(v, bytes) else str(v)
                for v in a.ravel().tolist()]
        if len(flat) <= MAX_VALUES:
            rec["values"] = flat
        else:
            rec["sha256"] = hashlib.sha256("\n".join(flat).encode()).hexdigest()
        return rec
    if a.dtype.kind == "c":
        a = np.stack([a.real, a.imag], axis=-1)
    if a.size <= MAX_VALUES:
        rec["values"] = to_json_numbers(a.ravel())
        return rec
    flat = np.ascontiguousarray(a.ravel())
    x = flat.astype(np.float64)
    finite = x[np.isfinite(x)]
    idx = np.linspace(0, x.size - 1, 200).round().astype(int)
    rec["summary"] = {
        "sha256": hashlib.sha256(flat.astype(flat.dtype.newbyteorder("<")).tobytes()).hexdigest(),
        "n_nonfinite": int(x.size - finite.size),
        "sum": float(finite.sum()), "sum_abs": float(np.abs(finite).sum()),
        "sum_sq": float((finite * finite).sum()),
        "min": float(finite.min()) if finite.size else None,
        "max": float(finite.max()) if finite.size else None,
        "sample": to_json_numbers(x[idx]),
    }
    return rec


def to_json_numbers(a: np.ndarray) -> list[Any]:
    """Array values as Python ints (integer dtypes) or floats (NaN/inf kept, as Python json does)."""
    return [int(v) for v in a] if a.dtype.kind in "biu" else [float(v) for v in a]


def read_hdf5(path: Path) -> dict[str, Any]:
    """Every dataset (arrays) and attribute of an HDF5 / NetCDF-4 file."""
    import h5py

    arrays: dict[str, Any] = {}
    attrs: dict[str, Any] = {}

    def attr_value(v: Any) -> Any:
        if isinstance(v, bytes):
            return v.decode("utf-8", errors="replace")
        if isinstance(v, np.ndarray):
            return [attr_value(x) for x in v.tolist()] if v.dtype.kind in "OSU" else \
                to_json_numbers(v.ravel())
        if isinstance(v, np.generic):
            return v.item()
        return v if isinstance(v, (int, float, str, bool)) or v is None else str(v)

    def visit(name: str, obj: Any) -> None:
        for k, v in obj.attrs.items():
            if k in ("DIMENSION_LIST", "REFERENCE_LIST", "_Netcdf4Dimid", "_Netcdf4Coordinates"):
                continue  # HDF5 object references / netCDF internals
            attrs[f"{name}@{k}"] = attr_value(v)
        if isinstance(obj, h5py.Dataset):
            data = obj[()]
            if isinstance(data, bytes):
                data = np.array([data.decode("utf-8", errors="replace")])
            arr = np.asarray(data)
            if arr.dtype.kind == "S":
                arr = arr.astype(str)
            arrays[name] = array_record(arr)

    with h5py.File(path, "r") as f:
        visit("/", f)
        f.visititems(visit)
    return {"kind": "arrays", "arrays": arrays, "attrs": attrs}


# --------------------------------------------------------------------------------------------
# snapshot
# --------------------------------------------------------------------------------------------

def package_info(env: dict[str, str]) -> dict[str, str]:
    code = ("import gmwm, gmwm.wv as w, numpy, scipy, numba\n"
            "print(gmwm.__file__); print(w.kernel_name());"
            "print(numpy.__version__, scipy.__version__, numba.__version__)")
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=False)
    lines = proc.stdout.split("\n")
    if proc.returncode != 0 or len(lines) < 3:
        return {"error": proc.stderr.strip()[-500:]}
    return {"gmwm": lines[0], "wv_kernel": lines[1], "numpy_scipy_numba": lines[2]}


def snapshot(outdir: Path, skip_readme: bool, skip_quick: bool, navchip: str | None) -> int:
    outdir.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    status_before = git_status(REPO)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True,
                            text=True, check=False).stdout.strip()
    pkg = package_info(env)
    if not pkg.get("gmwm", "").startswith(str(REPO / "src")):
        print(f"warning: gmwm is imported from {pkg.get('gmwm', '?')}, not from {REPO / 'src'} "
              f"(set PYTHONPATH={REPO / 'src'})", file=sys.stderr)
    manifest: dict[str, Any] = {
        "schema": SCHEMA, "repo": str(REPO), "commit": commit, "package": pkg,
        "python": sys.version.split()[0], "machine": platform.node(),
        "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "load_before": os.getloadavg(), "parts": {},
        "rules": {"skip": SKIP_RULES, "masks": MASKS, "duration": DURATION,
                  "timing_keys": TIMING_KEYS.pattern, "exclude": EXCLUDE_RULES,
                  "path_masks": PATH_MASKS, "max_values": MAX_VALUES},
    }
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="check_unchanged_") as tmp:
        scratch = Path(tmp)
        if not skip_readme:
            print("README commands:", flush=True)
            t0 = time.perf_counter()
            (scratch / "readme").mkdir()
            readme = run_readme(scratch / "readme", env)
            write_json(outdir / "readme.json", readme)
            manifest["parts"]["readme"] = {
                "seconds": round(time.perf_counter() - t0, 1),
                "run": [c["id"] for c in readme["commands"] if c["status"] == "run"],
                "skipped": [f"{c['id']}: {c['rule']}: {c['reason']}"
                            for c in readme["commands"] if c["status"] == "skipped"],
                "files": sorted(readme["files"]),
            }
        if not skip_quick:
            print("quick profile:", flush=True)
            (scratch / "quick").mkdir()
            data_dir = navchip_data_dir(navchip, env)
            quick = run_quick(scratch / "quick", env, data_dir)
            write_json(outdir / "quick.json", quick)
            manifest["parts"]["quick"] = {
                k: quick[k] for k in ("command", "returncode", "last_steps_line", "failed_rules",
                                      "seconds", "git_status_after")}
            manifest["parts"]["quick"]["navchip_data_dir"] = data_dir
            manifest["parts"]["quick"]["n_files"] = len(quick["files"])
            if quick["returncode"] != 0:
                shutil.copy(scratch / "quick" / "snakemake.log", outdir / "quick_snakemake.log")
                print(f"warning: the quick run failed (exit {quick['returncode']}, rules "
                      f"{quick['failed_rules']}); its log: {outdir / 'quick_snakemake.log'}",
                      file=sys.stderr)
    status_after = git_status(REPO)
    manifest.update(seconds=round(time.perf_counter() - t_all, 1), load_after=os.getloadavg(),
                    repo_status_before=status_before, repo_status_after=status_after)
    write_json(outdir / "manifest.json", manifest)
    if status_after != status_before:
        print("error: the repository's git status changed during the snapshot:\n"
              f"before:\n{status_before}after:\n{status_after}", file=sys.stderr)
        return 1
    print(f"snapshot written to {outdir} ({manifest['seconds']} s)")
    return 0


def write_json(path: Path, data: Any) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    os.replace(tmp, path)


# --------------------------------------------------------------------------------------------
# compare
# --------------------------------------------------------------------------------------------

def apply_masks(s: str, names: tuple[str, ...] | None = None) -> str:
    """``s`` with the masks of ``MASKS`` (or those named in ``names``) applied."""
    for name, pattern, repl in MASKS:
        if names is not None and name not in names:
            continue
        if repl is None:
            s = re.sub(pattern, lambda m: re.sub(DURATION, r"<T> \1", m.group(0)), s,
                       flags=re.MULTILINE)
        else:
            s = re.sub(pattern, repl, s, flags=re.MULTILINE)
    return s


SEPARATOR = re.compile(r"\s*\|?(\s*:?-+:?\s*\|)+\s*(:?-+:?\s*)?")


def mask_md_tables(lines: list[str]) -> list[str]:
    """Markdown table rows with the cells of timing columns (``TIMING_KEYS``) replaced by <T>."""
    out, header = [], None
    for k, line in enumerate(lines):
        if not line.lstrip().startswith("|"):
            header = None
            out.append(line)
            continue
        cells = line.strip().strip("|").split("|")
        nxt = lines[k + 1] if k + 1 < len(lines) else ""
        if SEPARATOR.fullmatch(line):
            pass
        elif header is None and SEPARATOR.fullmatch(nxt):
            header = [c.strip() for c in cells]
        elif header is not None and len(cells) == len(header):
            cells = ["<T>" if TIMING_KEYS.match(h) else c for h, c in zip(header, cells)]
            line = "|" + "|".join(cells) + "|"
        out.append(line)
    return out


def mask_text(s: str) -> tuple[str, list[int | float]]:
    """(template, numbers) of a text: masks applied, then every number replaced by '#'."""
    s = apply_masks(s)
    nums: list[int | float] = []

    def take(m: re.Match) -> str:
        t = m.group(0)
        nums.append(int(t) if re.fullmatch(r"[-+]?\d+", t) else float(t))
        return "#"

    return NUMBER.sub(take, s), nums


class Diffs:
    """Collected differences, printed as they come."""

    def __init__(self, rtol: float) -> None:
        self.rtol = rtol
        self.n = 0
        self.notes: list[str] = []

    def add(self, where: str, before: Any, after: Any) -> None:
        self.n += 1
        print(f"DIFF {where}\n    before: {short(before)}\n    after:  {short(after)}")

    def num_equal(self, a: Any, b: Any) -> bool:
        if isinstance(a, bool) or isinstance(b, bool) or not (
                isinstance(a, (int, float)) and isinstance(b, (int, float))):
            return a == b
        if isinstance(a, int) and isinstance(b, int):
            return a == b
        a, b = float(a), float(b)
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        if a == b:
            return True
        return abs(a - b) <= self.rtol * max(abs(a), abs(b))

    def scalar(self, where: str, a: Any, b: Any) -> None:
        """Compare two scalars: numbers with tolerance, strings masked, others exactly."""
        if isinstance(a, str) and isinstance(b, str):
            ta, na = mask_text(a)
            tb, nb = mask_text(b)
            if ta != tb or len(na) != len(nb) or not all(map(self.num_equal, na, nb)):
                self.add(where, a, b)
        elif not self.num_equal(a, b):
            self.add(where, a, b)

    def text(self, where: str, a: list[str], b: list[str]) -> None:
        """Compare two texts line by line: masked templates aligned, their numbers compared."""
        ma = [mask_text(x) for x in mask_md_tables(a)]
        mb = [mask_text(x) for x in mask_md_tables(b)]
        sm = difflib.SequenceMatcher(None, [t for t, _ in ma], [t for t, _ in mb], autojunk=False)
        for op, i1, i2, j1, j2 in sm.get_opcodes():
            if op == "equal":
                for i, j in zip(range(i1, i2), range(j1, j2)):
                    na, nb = ma[i][1], mb[j][1]
                    if not all(map(self.num_equal, na, nb)):
                        self.add(f"{where} line {i + 1}/{j + 1}", a[i], b[j])
            else:
                self.add(f"{where} lines {i1 + 1}-{i2} / {j1 + 1}-{j2} ({op})",
                         "\n            ".join(a[i1:i2]) or "(none)",
                         "\n            ".join(b[j1:j2]) or "(none)")


def short(v: Any, n: int = 400) -> str:
    s = v if isinstance(v, str) else json.dumps(v)
    return s if len(s) <= n else s[:n] + f"... ({len(s)} chars)"


def flatten(data: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(key path, scalar) pairs of a JSON tree."""
    if isinstance(data, dict):
        if not data:
            yield prefix or ".", {}
        for k, v in data.items():
            yield from flatten(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(data, list):
        if not data:
            yield prefix or ".", []
        for i, v in enumerate(data):
            yield from flatten(v, f"{prefix}[{i}]")
    else:
        yield prefix, data


def is_timing_key(path: str) -> bool:
    """Whether the last component of a key path ("a.b[2]", "group/array", "array@attr") is
    named by ``TIMING_KEYS``."""
    parts = [p for p in re.split(r"[./@\[\]]", path) if p and not p.isdigit()]
    return bool(parts) and bool(TIMING_KEYS.match(parts[-1]))


def compare_trees(d: Diffs, where: str, a: Any, b: Any) -> None:
    fa, fb = dict(flatten(a)), dict(flatten(b))
    for k in sorted(set(fa) | set(fb)):
        if k not in fb:
            d.add(f"{where} key {k} (removed)", fa[k], "(missing)")
        elif k not in fa:
            d.add(f"{where} key {k} (added)", "(missing)", fb[k])
        elif not is_timing_key(k):
            d.scalar(f"{where} key {k}", fa[k], fb[k])


def compare_tables(d: Diffs, where: str, a: dict[str, Any], b: dict[str, Any]) -> None:
    if a["columns"] != b["columns"]:
        d.add(f"{where} columns", a["columns"], b["columns"])
        return
    cols = a["columns"]
    if a["kind"] == "table-summary" or b["kind"] == "table-summary":
        if a["kind"] != b["kind"] or a["n_rows"] != b["n_rows"]:
            d.add(f"{where} rows", a.get("n_rows", len(a.get("rows", []))),
                  b.get("n_rows", len(b.get("rows", []))))
            return
        for c in cols:
            if TIMING_KEYS.match(c):
                continue
            compare_array(d, f"{where} column {c}", a["summary"][c], b["summary"][c])
        return
    ra, rb = a["rows"], b["rows"]
    if len(ra) != len(rb):
        d.add(f"{where} number of rows", len(ra), len(rb))
    for i, (x, y) in enumerate(zip(ra, rb)):
        names = " ".join(c for c in x if isinstance(c, str) and c.strip())
        label = f"{where} row {i + 1} ({short(names, 60)})"
        if len(x) != len(y):
            d.add(f"{label} cells", x, y)
            continue
        for c, u, v in zip(cols, x, y):
            if not TIMING_KEYS.match(c):
                d.scalar(f"{label} column {c}", u, v)


def compare_array(d: Diffs, where: str, a: dict[str, Any], b: dict[str, Any]) -> None:
    for k in ("shape", "dtype", "strings_sha256", "distinct"):
        if a.get(k) != b.get(k):
            d.add(f"{where} {k}", a.get(k), b.get(k))
            return
    if "values" in a or "values" in b:
        va, vb = a.get("values"), b.get("values")
        if va is None or vb is None or len(va) != len(vb):
            d.add(f"{where} values", va, vb)
            return
        bad = [i for i, (x, y) in enumerate(zip(va, vb)) if not d.num_equal(x, y)]
        if bad:
            shape = a["shape"] + ([2] if a["dtype"].startswith("complex") else [])
            at = tuple(int(k) for k in np.unravel_index(bad[0], shape)) if shape else ()
            d.add(f"{where}: {len(bad)} of {len(va)} values differ, the first at index {at}",
                  va[bad[0]], vb[bad[0]])
        return
    if "summary" in a and "summary" in b:
        sa, sb = a["summary"], b["summary"]
        if sa["sha256"] == sb["sha256"]:
            return
        for k in ("n_nonfinite", "sum", "sum_abs", "sum_sq", "min", "max"):
            if not d.num_equal(sa[k], sb[k]):
                d.add(f"{where} {k}", sa[k], sb[k])
        bad = [i for i, (x, y) in enumerate(zip(sa["sample"], sb["sample"]))
               if not d.num_equal(x, y)]
        if bad:
            d.add(f"{where} sampled values ({len(bad)} of {len(sa['sample'])})",
                  sa["sample"][bad[0]], sb["sample"][bad[0]])
        d.notes.append(f"{where}: bytes differ (sha256), statistics within rtol")
    elif a != b:
        d.add(f"{where}", a, b)


def compare_file(d: Diffs, where: str, a: dict[str, Any], b: dict[str, Any]) -> None:
    if a["kind"] != b["kind"] and {a["kind"], b["kind"]} != {"table", "table-summary"}:
        d.add(f"{where} kind", a["kind"], b["kind"])
        return
    kind = a["kind"]
    if kind == "text":
        d.text(where, a["lines"], b["lines"])
    elif kind in ("table", "table-summary"):
        compare_tables(d, where, a, b)
    elif kind == "tree":
        compare_trees(d, where, a["data"], b["data"])
    elif kind == "arrays":
        for name in sorted(set(a["arrays"]) | set(b["arrays"])):
            if is_timing_key(name) and name in a["arrays"] and name in b["arrays"]:
                continue
            if name not in a["arrays"] or name not in b["arrays"]:
                d.add(f"{where} array {name!r}", name in a["arrays"], name in b["arrays"])
            else:
                compare_array(d, f"{where} array {name!r}", a["arrays"][name], b["arrays"][name])
        compare_trees(d, f"{where} attrs", a.get("attrs", {}), b.get("attrs", {}))
    elif kind == "excluded":
        pass
    elif a != b:
        d.add(where, a, b)


def masked_paths(files: dict[str, Any]) -> dict[str, Any]:
    """Files keyed by their path with ``PATH_MASKS`` applied (archive/<date>-<hash>/...)."""
    out: dict[str, Any] = {}
    for rel, rep in files.items():
        key = apply_masks(rel, PATH_MASKS)
        n, k = 1, key
        while k in out:  # two paths masked alike: keep both, in path order
            n += 1
            k = f"{key} ({n})"
        out[k] = rep
    return out


def compare_files(d: Diffs, part: str, fa: dict[str, Any], fb: dict[str, Any]) -> None:
    fa, fb = masked_paths(dict(sorted(fa.items()))), masked_paths(dict(sorted(fb.items())))
    for rel in sorted(set(fa) | set(fb)):
        where = f"{part}: {rel}"
        if rel not in fb:
            d.add(f"{where} (file removed)", "exists", "(missing)")
        elif rel not in fa:
            d.add(f"{where} (file added)", "(missing)", "exists")
        else:
            compare_file(d, where, fa[rel], fb[rel])


def compare(before: Path, after: Path, rtol: float) -> int:
    d = Diffs(rtol)
    parts = [p for p in ("readme", "quick") if (before / f"{p}.json").exists()
             or (after / f"{p}.json").exists()]
    for part in parts:
        pa, pb = before / f"{part}.json", after / f"{part}.json"
        if not (pa.exists() and pb.exists()):
            d.add(f"{part}: part of the snapshot", "present" if pa.exists() else "(not taken)",
                  "present" if pb.exists() else "(not taken)")
            continue
        a, b = json.loads(pa.read_text()), json.loads(pb.read_text())
        print(f"== {part}")
        if part == "readme":
            # commands are matched by their text, whitespace collapsed (not by position)
            ca = {" ".join(c["command"].split()): c for c in a["commands"]}
            cb = {" ".join(c["command"].split()): c for c in b["commands"]}
            for cmd in [*ca, *(k for k in cb if k not in ca)]:
                x, y = ca.get(cmd), cb.get(cmd)
                title = (x or y)["id"]
                if x is None or y is None:
                    d.add(f"readme: command {title!r}", "present" if x else "(missing)",
                          "present" if y else "(missing)")
                    continue
                for k in ("status", "returncode", "session"):
                    if x.get(k) != y.get(k):
                        d.add(f"readme: {title} {k}", x.get(k), y.get(k))
                for k in ("stdout", "stderr", "expected"):
                    d.text(f"readme: {title} {k}", (x.get(k) or "").splitlines(),
                           (y.get(k) or "").splitlines())
        else:
            for k in ("returncode", "last_steps_line", "failed_rules", "navchip_data_dir"):
                x, y = (apply_masks(v) if isinstance(v, str) else v for v in (a.get(k), b.get(k)))
                if x != y:
                    d.add(f"quick: {k}", a.get(k), b.get(k))
            if (a.get("navchip_data_dir") is None) != (b.get("navchip_data_dir") is None):
                d.notes.append("one quick run had no Navchip data (its navchip rules fail): "
                               "snapshot again with --navchip-data DIR (the directory holding "
                               "wv/navchip_wv.csv)")
        compare_files(d, part, a["files"], b["files"])
    for note in d.notes:
        print(f"note: {note}")
    print(f"{d.n} difference(s) between {before} and {after} (rtol {rtol:g}; parts: "
          f"{', '.join(parts)})")
    return 1 if d.n else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("snapshot", help="run the README examples and the quick profile")
    s.add_argument("outdir", type=Path)
    s.add_argument("--skip-readme", action="store_true", help="do not run the README commands")
    s.add_argument("--skip-quick", action="store_true", help="do not run the quick profile")
    s.add_argument("--navchip-data", metavar="DIR",
                   help="directory holding wv/navchip_wv.csv for the quick run ('none': do not "
                        "pass one); default: the dataset registry's local copy if present")
    c = sub.add_parser("compare", help="compare two snapshots; exit 1 if they differ")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    c.add_argument("--rtol", type=float, default=1e-9,
                   help="relative tolerance of floats (integers: exact); default 1e-9")
    a = p.parse_args(argv)
    if a.cmd == "snapshot":
        out = a.outdir.resolve()
        if out == REPO or REPO in out.parents:
            p.error("OUTDIR must be outside the repository")
        return snapshot(out, a.skip_readme, a.skip_quick, a.navchip_data)
    return compare(a.before, a.after, a.rtol)


if __name__ == "__main__":
    sys.exit(main())
