"""Shared start of every workflow script: thread limits, per-job CPU record and logging.

Import it before numpy, numba or the library (every script's first import). On import it

* limits every threaded library of the job to the rule's ``threads`` (1 unless the rule declares
  more): Snakemake runs one job per core, so a job that also used every core for BLAS, Numba or
  the WV kernel (``GMWM_NUM_THREADS``; by default all cores for signals >= 2^17 samples) would
  compete with the other job for the same cores;
* registers an exit hook that writes the job's own CPU time (``getrusage`` of the process and of
  its waited-for children, exact, unlike the polled ``cpu_time`` of Snakemake's benchmark file)
  beside the rule's benchmark file as ``<benchmark>.rusage.json`` (the Snakefile passes the
  benchmark patterns in ``GMWM_BENCHMARK_PATTERNS``), which ``gmwm_studies.archive.read_benchmarks``
  adds to the archive's ``timings.csv``, and as the log's last line.
"""

import atexit
import json
import logging
import os
import resource
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


def cpu_record() -> dict:
    """CPU seconds of this process and of its waited-for children (``getrusage``), wall seconds
    since this module was imported and the peak resident set [MB]."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    user = me.ru_utime + kids.ru_utime
    system = me.ru_stime + kids.ru_stime
    return {"cpu_s": user + system, "user_s": user, "system_s": system,
            "wall_s": time.perf_counter() - _START,
            "max_rss_mb": max(me.ru_maxrss, kids.ru_maxrss) / 1024.0}


def _write_cpu_record(snakemake, logger: logging.Logger | None) -> None:
    rec = cpu_record()
    rec["threads"] = int(snakemake.threads)
    if logger is not None:
        logger.info("job CPU %.2f s (user %.2f, system %.2f), wall %.2f s, peak RSS %.0f MB",
                    rec["cpu_s"], rec["user_s"], rec["system_s"], rec["wall_s"], rec["max_rss_mb"])
    path = benchmark_path(snakemake)
    if path is None:
        return
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    # written by rename, like every output: a reader never sees half a record
    tmp = f"{path}.rusage.json.tmp{os.getpid()}"
    with open(tmp, "w") as fh:
        json.dump(rec, fh)
    os.replace(tmp, f"{path}.rusage.json")


_SNAKEMAKE = _job()
_LOGGER: list = [None]
if _SNAKEMAKE is not None:
    limit_threads(_SNAKEMAKE.threads)
    atexit.register(lambda: _write_cpu_record(_SNAKEMAKE, _LOGGER[0]))


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
    _LOGGER[0] = logger
    return logger
