"""benchmarks/check_unchanged.py: README command extraction, masks, normalised files and the
comparison of two snapshots (on small hand-made snapshots: no command is run)."""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from conftest import load_benchmark

cu = load_benchmark("check_unchanged")


def test_readme_commands_run_the_examples_and_skip_install_tests_and_pipeline():
    cmds = cu.readme_commands(cu.REPO / "README.md")
    skipped = {cu.skip_reason(c["command"])[0] for c in cmds if cu.skip_reason(c["command"])}
    assert skipped == {"install", "tests", "quick-profile", "pipeline"}
    run = [c for c in cmds if not cu.skip_reason(c["command"])]
    fit = [c for c in run if c["command"].startswith("gmwm fit x.npy")]
    assert len(fit) == 1
    # the output the README shows after a block is kept with the block's last command
    assert any("RW[1].gamma2" in (c["expected"] or "") for c in run)
    heredocs = [c["command"] for c in run if c["command"].startswith("python - <<'PY'")]
    assert all(h.rstrip().endswith("\nPY") for h in heredocs)
    assert any("mktemp -d" in c["command"].splitlines()[0] for c in run)
    sim = [c["command"] for c in run if c["command"].startswith('gmwm simulate "WN+RW+AR1+SIN"')]
    assert len(sim) == 1 and sim[0].rstrip().endswith("-o x.npy")  # continuation lines joined


@pytest.mark.parametrize(("text", "template", "numbers"), [
    ("objective 0.165422, converged yes; WV 0.008 s, fit 0.043 s",
     "objective #, converged yes; WV <T> s, fit <T> s", [0.165422]),
    ("wrote 900000 samples to x.npy [3.713 s]", "wrote # samples to x.npy [<T> s]", [900000]),
    ("AD minimum at tau = 655.4 s", "AD minimum at tau = # s", [655.4]),  # a result: kept
    ("Run time (summed job wall time): 238.5 s (fit 2 jobs 143.9 s).",
     "Run time (summed job wall time): <T> s (fit # jobs <T> s).", [2]),
    ("generated 2026-11-25 14:34 UTC at commit f90618f in /tmp/pytest-1/x.csv",
     "generated <DATE> at commit <HEX> in <PATH>", []),
    ("WN[1].sigma2  9.96962e-05  u/sqrt(Hz)", "WN[#].sigma2  #  u/sqrt(Hz)", [1, 9.96962e-05]),
    ("noise_density: 8.337367e-04  # from ax", "noise_density: #  # from ax", [8.337367e-04]),
    ("1234567e-4 and 1234567e", "# and <HEX>", [1234567e-4]),
    ("archive/20261125T153105Z-03ff69e0ab/git.txt", "archive/<DATE>-<HEX>/git.txt", []),
])
def test_masks(text, template, numbers):
    assert cu.mask_text(text) == (template, numbers)


def test_timing_keys_and_markdown_timing_columns():
    for key in ("seconds", "global.seconds", "armav/seconds_fit", "/@seconds", "mean_seconds",
                "gmwm_median_s", "speedup_mean", "max_rss_mb", "cpu_time"):
        assert cu.is_timing_key(key), key
    for key in ("scale_s", "time_s", "estimate", "mean"):
        assert not cu.is_timing_key(key), key
    lines = ["| method | mean_seconds | rmse |", "|---|---|---|", "| gmwm | 0.34 | 0.01 |"]
    assert cu.mask_md_tables(lines)[2] == "| gmwm |<T>| 0.01 |"


def _png(path: Path, w: int, h: int) -> None:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = b"".join(b"\0" + b"\0" * w for _ in range(h))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def _files(root: Path, value: float, seconds: float, stamp: str) -> dict:
    root.mkdir()
    (root / "t.csv").write_text(f"parameter,estimate,seconds\nWN,{value!r},{seconds}\n")
    (root / "r.md").write_text(f"# r\n\ngenerated {stamp}\n\n| p | value |\n|---|---|\n"
                               f"| WN | {value:.6g} |\n")
    (root / "f.json").write_text(json.dumps({"theta": [value, 2], "seconds": seconds}))
    np.save(root / "x.npy", np.arange(30_000, dtype=float) * value)
    _png(root / "fig.png", 3, 2)
    (root / "logs").mkdir()
    (root / "logs" / "job.log").write_text(f"{stamp} took {seconds} s\n")
    return cu.collect_tree(root)


def _snapshot(tmp: Path, name: str, value: float, seconds: float, stamp: str) -> Path:
    out = tmp / name
    files = _files(tmp / f"{name}_files", value, seconds, stamp)
    out.mkdir()
    cu.write_json(out / "quick.json", {"returncode": 0, "last_steps_line": "3 of 3 steps (100%) done",
                                       "failed_rules": [], "files": files})
    cmd = {"id": "01 gmwm fit", "command": "gmwm fit x.npy WN", "status": "run", "session":
           "session0", "returncode": 0, "expected": None, "stderr": "",
           "stdout": f"WN[1].sigma2 {value:.6g}\nWV {seconds} s, fit {seconds} s\n"}
    cu.write_json(out / "readme.json", {"commands": [cmd], "files": {}})
    return out


def test_normalised_files(tmp_path):
    files = _files(tmp_path / "f", 0.25, 1.5, "2026-01-01")
    assert files["fig.png"] == {"kind": "image", "width": 3, "height": 2}
    assert files["t.csv"]["rows"] == [["WN", 0.25, 1.5]]
    assert files["x.npy"]["arrays"][""]["summary"]["max"] == pytest.approx(0.25 * 29_999)
    assert files["logs/job.log"] == {"kind": "excluded", "rule": "job-logs"}


def test_compare_ignores_timings_dates_and_flags_a_changed_number(tmp_path, capsys):
    a = _snapshot(tmp_path, "a", 0.25, 1.5, "2026-01-01 10:00 UTC")
    b = _snapshot(tmp_path, "b", 0.25, 9.75, "2027-02-03 11:11 UTC")
    assert cu.compare(a, b, 1e-9) == 0
    c = _snapshot(tmp_path, "c", 0.2501, 1.5, "2026-01-01 10:00 UTC")
    capsys.readouterr()
    assert cu.compare(a, c, 1e-9) == 1
    out = capsys.readouterr().out
    for where in ("t.csv row 1", "column estimate", "r.md", "f.json key theta[0]", "x.npy",
                  "readme: 01 gmwm fit stdout"):
        assert where in out, where
    assert cu.compare(a, c, 1e-3) == 0  # within the tolerance
