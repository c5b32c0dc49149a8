"""Shared start of every workflow script: thread limits, per-job CPU record and logging.

Import it before numpy, numba or the library (every script's first import). On import it

* limits every threaded library of the job to the rule's ``threads`` (1 unless the rule declares
  more): Snakemake runs one job per core, so a job that also used every core for BLAS, Numba or
  the WV kernel (``GMWM_NUM_THREADS``; by default all cores for signals >= 2^17 samples) would
  compete with the other job for the same cores;
* records the job's exact CPU time: the script's process forks at this import (only the
  standard library and Snakemake's preamble are loaded by then, no thread runs); the child runs
  the script, the parent waits for it and takes its ``rusage`` from ``wait4`` (the child and its
  waited-for children, interpreter finalization included: ~20 % of a job's import cost, which an
  exit hook inside the script would miss), adds its own, and writes the record beside the rule's
  benchmark file as ``<benchmark>.rusage.json`` (the Snakefile passes the benchmark patterns in
  ``GMWM_BENCHMARK_PATTERNS``; ``gmwm_studies.archive.read_benchmarks`` adds it to the archive's
  ``timings.csv`` as ``cpu_s``) and as the log's last line, then exits with the child's status.
  Snakemake's own ``cpu_time`` is polled, a lower bound.
"""

import json
import logging
import os
import resource
import signal
import sys
import time

#: environment variables of the threaded libraries a job may load (read when each is imported,
#: ``GMWM_NUM_THREADS`` at every WV call)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS",
                    "GMWM_NUM_THREADS")

_START = time.perf_counter()


def _job():
    """The ``snakemake`` object Snakemake's preamble put in the script's globals (None outside
    a Snakemake job)."""
    main = sys.modules.get("__main__")
    return getattr(main, "snakemake", None)


def limit_threads(threads: int) -> None:
    """Set every variable of :data:`THREAD_VARIABLES` to ``threads`` (>= 1)."""
    n = str(max(1, int(threads)))
    for name in THREAD_VARIABLES:
        os.environ[name] = n


def benchmark_path(snakemake) -> str | None:
    """This job's benchmark file, from the rule's pattern in ``GMWM_BENCHMARK_PATTERNS`` and the
    job's wildcards; None when the rule has none."""
    try:
        patterns = json.loads(os.environ.get("GMWM_BENCHMARK_PATTERNS", "{}"))
    except ValueError:
        return None
    pattern = patterns.get(snakemake.rule)
    if not pattern:
        return None
    return pattern.format(**dict(snakemake.wildcards.items()))


def cpu_record(child: resource.struct_rusage | None = None) -> dict:
    """CPU seconds of this process and of ``child`` (its rusage from ``wait4``; default: the
    waited-for children; both from the interpreter's start), wall seconds since this module was
    imported (the interpreter's start-up and Snakemake's preamble not included), peak resident
    set [MB]."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN) if child is None else child
    user = me.ru_utime + kids.ru_utime
    system = me.ru_stime + kids.ru_stime
    return {"cpu_s": user + system, "user_s": user, "system_s": system,
            "wall_s": time.perf_counter() - _START,
            "max_rss_mb": max(me.ru_maxrss, kids.ru_maxrss) / 1024.0}


def _write_cpu_record(snakemake, rec: dict) -> None:
    rec["threads"] = int(snakemake.threads)
    if len(snakemake.log):
        with open(snakemake.log[0], "a") as fh:
            fh.write(time.strftime("%Y-%m-%d %H:%M:%S") +
                     " INFO job CPU %.2f s (user %.2f, system %.2f), wall %.2f s, peak RSS %.0f MB"
                     "\n" % (rec["cpu_s"], rec["user_s"], rec["system_s"], rec["wall_s"],
                             rec["max_rss_mb"]))
    path = benchmark_path(snakemake)
    if path is None:
        return
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    # written by rename, like every output: a reader never sees half a record
    tmp = f"{path}.rusage.json.tmp{os.getpid()}"
    with open(tmp, "w") as fh:
        json.dump(rec, fh)
    os.replace(tmp, f"{path}.rusage.json")


def _run_in_child(snakemake) -> None:
    """Fork; in the parent wait for the child, write its CPU record and exit with its status
    (never returns); in the child return and let the script run."""
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        return
    while True:
        try:
            _, status, usage = os.wait4(pid, 0)
            break
        except InterruptedError:
            continue
    code = os.waitstatus_to_exitcode(status)
    try:
        _write_cpu_record(snakemake, cpu_record(usage))
    except OSError as exc:  # the job's result stands; only its CPU record is missing
        print(f"wflog: could not write the CPU record: {exc}", file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    # a child killed by a signal: the same signal here, so Snakemake sees what happened
    if code < 0:
        try:
            signal.signal(-code, signal.SIG_DFL)
        except (OSError, ValueError):  # SIGKILL and SIGSTOP keep their default anyway
            pass
        os.kill(os.getpid(), -code)
    os._exit(code)  # nothing of the script ran here: no finalization to wait for


_SNAKEMAKE = _job()
if _SNAKEMAKE is not None:
    limit_threads(_SNAKEMAKE.threads)
    if hasattr(os, "fork") and hasattr(os, "wait4"):  # POSIX; elsewhere no record is written
        _run_in_child(_SNAKEMAKE)


def get_logger(snakemake) -> logging.Logger:
    """Logger writing to ``snakemake.log[0]`` with timestamps; one per job."""
    name = f"gmwm.{snakemake.rule}"
    logger = logging.getLogger(name)
    logger.setLevel(logging.INFO)
    fmt = logging.Formatter("%(asctime)s %(levelname)s %(message)s", "%Y-%m-%d %H:%M:%S")
    handlers = [logging.StreamHandler(sys.stderr)]
    if len(snakemake.log):
        handlers.append(logging.FileHandler(snakemake.log[0], mode="w"))
    for h in handlers:
        h.setFormatter(fmt)
        logger.addHandler(h)
    return logger
