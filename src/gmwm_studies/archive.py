"""Run bookkeeping of the pipeline: config hash, job timings, the index page and the run archive.

The Snakemake workflow names each run by :func:`config_hash`, collects its ``benchmark:`` files
with :func:`read_benchmarks`, renders ``index.md`` with :func:`render_index` and copies a finished
run's reports into a never-overwritten archive directory with :func:`make_archive`.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import subprocess
from collections.abc import Iterable, Mapping, Sequence
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm_studies.montecarlo import format_markdown_table

__all__ = ["config_hash", "git_commit", "make_archive", "package_versions", "read_benchmarks",
           "render_index", "run_summary"]



def config_hash(config: Mapping[str, Any], length: int = 10) -> str:
    """Short SHA-256 of the config (keys sorted), naming the archive of a run with this config."""
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:length]


def read_benchmarks(paths: Iterable[str | os.PathLike]) -> pd.DataFrame:
    """Collect Snakemake ``benchmark:`` files laid out as ``.../<rule>/<study>/<job>.tsv``.

    Missing files are skipped (their job ran in an earlier session whose benchmark was removed).
    Returns one row per job: rule, study, job, seconds (wall), max_rss_mb, cpu_time [s], cpu_s
    [s]. ``cpu_time`` is Snakemake's polled CPU time (psutil every 1 s for the first 30 s, then
    every 30 s): what a job used after the last poll is missing, so it is a lower bound (a
    5-replicate SVO training job logged 14.5 s against ~24 s measured); ``seconds`` is exact.
    ``cpu_s`` is exact: the job's own ``getrusage`` (itself and its children) written at its
    exit beside the benchmark as ``<job>.tsv.rusage.json`` (``workflow/scripts/wflog.py``); NaN
    when that file is absent (a job that failed before its script started, an older run).
    """
    rows = []
    for path in map(Path, paths):
        if not path.exists():
            continue
        table = pd.read_csv(path, sep="\t")
        if table.empty:
            continue
        last = table.iloc[-1]
        rows.append(
            {
                "rule": path.parent.parent.name,
                "study": path.parent.name,
                "job": path.stem,
                "seconds": _num(last.get("s", np.nan)),
                "max_rss_mb": _num(last.get("max_rss", np.nan)),
                "cpu_time": _num(last.get("cpu_time", np.nan)),
                "cpu_s": _rusage_cpu(path),
            }
        )
    return pd.DataFrame(rows, columns=["rule", "study", "job", "seconds", "max_rss_mb",
                                       "cpu_time", "cpu_s"])


def _rusage_cpu(bench: Path) -> float:
    """``cpu_s`` of the job's ``<benchmark>.rusage.json`` (NaN when absent or unreadable)."""
    side = bench.with_name(bench.name + ".rusage.json")
    try:
        return _num(json.loads(side.read_text()).get("cpu_s"))
    except (OSError, ValueError, AttributeError):
        return float("nan")


def _num(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def run_summary(bench: pd.DataFrame) -> pd.DataFrame:
    """Jobs and summed wall time [s] per study and rule (from :func:`read_benchmarks`)."""
    if bench.empty:
        return pd.DataFrame(columns=["study", "rule", "jobs", "seconds"])
    return (
        bench.groupby(["study", "rule"], sort=True)
        .agg(jobs=("job", "count"), seconds=("seconds", "sum"))
        .reset_index()
    )


def archived_summary(archive_root: str | os.PathLike, studies: Iterable[str],
                     aliases: Mapping[str, str] | None = None
                     ) -> tuple[pd.DataFrame, dict[str, str]]:
    """:func:`run_summary` rows of each study from the newest archive under ``archive_root``
    whose ``timings.csv`` has jobs of it, and the archive name per study found.

    For the index of a partial rerun: studies that did not run this time keep the timings of
    the run that produced their committed reports. Archive names start with a UTC timestamp, so
    name order is time order. ``aliases`` maps a benchmark directory name to the study it
    belongs to (e.g. the SVO section's ``case1``, ``case2``)."""
    wanted = set(studies)
    root = Path(archive_root)
    frames, source = [], {}
    runs = sorted((d for d in root.iterdir() if (d / "timings.csv").is_file()),
                  key=lambda d: d.name, reverse=True) if root.is_dir() else []
    for run in runs:
        if not wanted:
            break
        table = pd.read_csv(run / "timings.csv")
        table["study"] = table["study"].replace(dict(aliases or {}))
        found = wanted & set(table["study"])
        if found:
            frames.append(table[table["study"].isin(found)])
            source.update({name: run.name for name in found})
            wanted -= found
    bench = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(
        columns=["rule", "study", "job", "seconds"])
    return run_summary(bench), source


def render_index(studies: Sequence[Mapping[str, Any]], summary: pd.DataFrame,
                 config_id: str, sources: Mapping[str, str] | None = None) -> str:
    """Markdown index page: per study its description, figures, key numbers and run time.

    Each entry of ``studies``: name, model, description, n_samples (list), replicates, figures
    (relative paths), table (relative path of the Markdown table), key (DataFrame of key numbers).
    ``sources``: per study, the archive its run time comes from (when not from this run).
    """
    lines = [
        "# GMWM reproduction: studies at a glance",
        "",
        ("Verdict for every figure and table of the papers (agrees / differs / not reproducible): "
         "[REPRODUCTION.md](REPRODUCTION.md); the per-replicate counts it quotes: "
         "[counts.md](counts.md)."),
        "",
        f"Config hash `{config_id}`; generated {datetime.now(UTC):%Y-%m-%d %H:%M} UTC.",
        "",
    ]
    for s in studies:
        lines += [f"## {s['name']}: `{s['model']}`", ""]
        if s.get("description"):
            lines += [str(s["description"]), ""]
        if "n_samples" in s:
            sizes = ", ".join(str(t) for t in s["n_samples"])
            lines.append(f"Sample sizes {sizes}; {s['replicates']} replicates each. "
                         f"Full table: [{s['table']}]({s['table']}).")
        else:  # a real-data section: no design to state
            lines.append(f"Full table: [{s['table']}]({s['table']}).")
        lines.append("")
        for fig in s.get("figures", []):
            lines += [f"![{Path(fig).stem}]({fig})", ""]
        key = s.get("key")
        if key is not None and len(key):
            lines += [format_markdown_table(key, digits=3), ""]
        own = summary[summary["study"] == s["name"]] if len(summary) else summary
        if len(own):
            total = own["seconds"].sum()
            per_rule = ", ".join(
                f"{r.rule} {r.jobs} jobs {r.seconds:.1f} s" for r in own.itertuples(index=False)
            )
            origin = (sources or {}).get(s["name"])
            where = f", run archived as `archive/{origin}`" if origin else ""
            lines += [f"Run time (summed job wall time{where}): {total:.1f} s ({per_rule}).", ""]
    return "\n".join(lines) + "\n"


def package_versions(names: Sequence[str] = ("gmwm", "numpy", "scipy", "numba", "xarray",
                                              "h5py", "netCDF4", "pandas", "matplotlib",
                                              "snakemake", "snakemake-executor-plugin-slurm")
                     ) -> dict[str, str]:
    """Installed versions of the packages a run depends on ("not installed" if absent)."""
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _git(repo: str | os.PathLike, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, check=True,
                          timeout=20).stdout


def git_commit(repo: str | os.PathLike = ".",
               outputs: Iterable[str | os.PathLike] = ()) -> str:
    """Commit of ``repo``: its full hash, with ``-dirty`` when a tracked file other than
    ``outputs`` differs from it; "unknown" outside git.

    ``outputs`` are the run's own files (the reports it rewrites): their changes are the run's
    doing, not a change of code or config, so they do not make the commit dirty.
    """
    try:
        root = Path(_git(repo, "rev-parse", "--show-toplevel").strip())
        sha = _git(repo, "rev-parse", "HEAD").strip()
        status = _git(repo, "status", "--porcelain=v1", "-z", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    entries = iter(status.split("\0"))
    changed = []
    for entry in entries:
        if not entry:
            continue
        changed.append((root / entry[3:]).resolve())
        if entry[0] in "RC":  # a rename or copy is followed by its source path
            changed.append((root / next(entries, "")).resolve())
    produced = {Path(p).resolve() for p in outputs}
    return sha + ("-dirty" if any(p not in produced for p in changed) else "")


def make_archive(
    archive_root: str | os.PathLike,
    config: Mapping[str, Any],
    files: Iterable[str | os.PathLike],
    bench: pd.DataFrame,
    repo: str | os.PathLike = ".",
    base: str | os.PathLike = ".",
    produced: Iterable[str | os.PathLike] = (),
) -> Path:
    """Copy a run's reports into a new ``<archive_root>/<UTC timestamp>-<config hash>/``.

    Never overwrites: if the directory exists a numeric suffix is added. The archive holds the
    files (paths kept relative to ``base``), ``config.json``, ``versions.json``, ``git.txt`` (the
    commit of ``repo``, ``-dirty`` only when a tracked file other than ``files`` was changed: see
    :func:`git_commit`; ``produced``: the run's other outputs, written but not archived, which
    do not make it dirty either) and ``timings.csv`` (one row per job). It is assembled under a hidden
    temporary name and renamed into place, so a partial archive never looks complete.
    """
    files = list(files)
    root = Path(archive_root)
    root.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    name = f"{stamp}-{config_hash(config)}"
    tmp = root / f".{name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        base = Path(base)
        for f in files:
            src = Path(f)
            rel = src.resolve().relative_to(base.resolve()) if src.is_absolute() else src
            dst = tmp / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
        write_json_atomic(tmp / "config.json", dict(config))
        write_json_atomic(tmp / "versions.json", package_versions())
        write_text_atomic(tmp / "git.txt",
                          git_commit(repo, outputs=[*files, *produced]) + "\n")
        write_text_atomic(tmp / "timings.csv", bench.to_csv(index=False))
        target = root / name
        k = 1
        while True:
            try:
                # os.rename onto an existing non-empty directory fails, so this never overwrites.
                os.rename(tmp, target)
                return target
            except OSError:
                if not target.exists():
                    raise
                target = root / f"{name}-{k}"
                k += 1
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
