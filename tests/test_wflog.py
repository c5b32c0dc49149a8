"""The workflow scripts' shared start (workflow/scripts/wflog.py): thread limits and the per-job
CPU record the archive reads."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from gmwm_studies.archive import read_benchmarks

SCRIPTS = Path(__file__).resolve().parents[1] / "workflow" / "scripts"


def _run_job(tmp_path: Path, threads: int, tail: str = "") -> subprocess.CompletedProcess:
    """Run a stand-in script job (a ``snakemake`` object in ``__main__`` as Snakemake's preamble
    leaves it) that imports wflog, then numpy, spins and prints its thread variables, then runs
    ``tail``."""
    script = tmp_path / "job.py"
    script.write_text(textwrap.dedent(f"""
        import json, os, sys, types
        sys.path.insert(0, {str(SCRIPTS)!r})

        class W(dict):
            pass

        snakemake = types.SimpleNamespace(rule="simulate_wv", threads={threads},
                                          wildcards=W(study="s1", T="100", chunk="0"),
                                          log=[{str(tmp_path / "job.log")!r}])
        from wflog import THREAD_VARIABLES, get_logger
        import numpy as np
        log = get_logger(snakemake)
        x = 0.0
        for i in range(200000):
            x += i * 0.5
        print(json.dumps({{v: os.environ.get(v) for v in THREAD_VARIABLES}}))
    """) + tail)
    env = dict(os.environ, OMP_NUM_THREADS="7", GMWM_NUM_THREADS="9",
               GMWM_BENCHMARK_PATTERNS=json.dumps(
                   {"simulate_wv": "bench/simulate_wv/{study}/T{T}_c{chunk}.tsv"}))
    return subprocess.run([sys.executable, str(script)], check=False, cwd=tmp_path, env=env,
                          capture_output=True, text=True)


def _printed(out: subprocess.CompletedProcess) -> dict:
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_job_threads_set_and_cpu_recorded_beside_benchmark(tmp_path):
    seen = _printed(_run_job(tmp_path, threads=1))
    assert set(seen.values()) == {"1"}  # the parent's 7 and 9 are overridden
    bench = tmp_path / "bench" / "simulate_wv" / "s1" / "T100_c0.tsv"
    rec = json.loads((bench.parent / "T100_c0.tsv.rusage.json").read_text())
    assert rec["threads"] == 1
    assert rec["cpu_s"] > 0 and abs(rec["cpu_s"] - rec["user_s"] - rec["system_s"]) < 1e-9
    assert "job CPU" in (tmp_path / "job.log").read_text().splitlines()[-1]
    # read_benchmarks joins the record to Snakemake's benchmark row
    bench.write_text("s\th:m:s\tmax_rss\tcpu_time\n1.5\t0:00:01\t100\t0.25\n")
    other = tmp_path / "bench" / "fit" / "s1" / "x.tsv"
    other.parent.mkdir(parents=True)
    other.write_text("s\th:m:s\tmax_rss\tcpu_time\n2.0\t0:00:02\t100\t1.0\n")
    table = read_benchmarks([bench, other, tmp_path / "missing.tsv"])
    assert list(table["rule"]) == ["simulate_wv", "fit"]
    assert table["cpu_s"].iloc[0] == rec["cpu_s"]
    assert table["cpu_s"].isna().iloc[1]  # no record: NaN, not the polled value


def test_declared_threads_are_passed_on(tmp_path):
    assert set(_printed(_run_job(tmp_path, threads=3)).values()) == {"3"}


def test_failing_job_keeps_its_status_and_record(tmp_path):
    out = _run_job(tmp_path, threads=1, tail="raise SystemExit(3)\n")
    assert out.returncode == 3
    rec = tmp_path / "bench" / "simulate_wv" / "s1" / "T100_c0.tsv.rusage.json"
    assert json.loads(rec.read_text())["cpu_s"] > 0
    out = _run_job(tmp_path, threads=1, tail="import os, signal\nos.kill(os.getpid(), 9)\n")
    assert out.returncode == -9  # killed child: the parent dies of the same signal


def test_record_includes_the_child_s_finalization(tmp_path):
    # work done after every exit hook (a finalizer at interpreter teardown) is counted too
    tail = textwrap.dedent("""
        import atexit, resource
        class Late:
            def __del__(self):
                x = 0
                for i in range(3_000_000):
                    x += i
        late = Late()
        def report():
            r = resource.getrusage(resource.RUSAGE_SELF)
            print("hook", r.ru_utime + r.ru_stime, flush=True)
        atexit.register(report)
    """)
    out = _run_job(tmp_path, threads=1, tail=tail)
    assert out.returncode == 0, out.stderr
    at_hook = float(out.stdout.split("hook")[-1])
    rec = json.loads((tmp_path / "bench" / "simulate_wv" / "s1" /
                      "T100_c0.tsv.rusage.json").read_text())
    assert rec["cpu_s"] > at_hook + 0.05  # the 3e6-step loop ran after the hook
