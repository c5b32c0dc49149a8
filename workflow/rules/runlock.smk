# Resuming a killed run with the same command.
#
# Snakemake marks a running workflow with lock files in .snakemake/locks/ (file persistence
# backend, the default) and refuses to start while they exist; a SIGKILLed run leaves them behind,
# and `snakemake --unlock` is then needed. The lock files do not say whether their owner is alive,
# so the main process of every invocation on this outdir (run, dry run, --report, ...) also holds
# an OS lock (flock) on .snakemake/gmwm-run.flock for its whole life: shared normally, exclusive
# only while it checks for stale locks at start. The kernel drops a flock when its holder dies,
# however it dies. So: exclusive flock obtained => no other Snakemake main process is alive on
# this outdir => any lock files are stale and are removed. If another process holds the flock
# (for longer than RUNLOCK_WAIT_S, e.g. a running workflow), nothing is touched and Snakemake's
# own check decides (it refuses a second run on the same files).
#
# Cluster jobs (remote mode) and local job processes never take the flock. Not covered: runs with
# --nolock or the db persistence backend, and runs of a Snakefile without this file.

import fcntl
import shutil
import time
from pathlib import Path

from snakemake.logging import logger

RUNLOCK_WAIT_S = 30  # another short invocation (dry run, --report) holding the flock: wait


def _flock_exclusive(fh, wait_s):
    """Try an exclusive flock on ``fh`` for up to ``wait_s`` seconds; True if obtained."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.5)


def clear_stale_locks(snakemake_dir=Path(".snakemake"), wait_s=RUNLOCK_WAIT_S):
    """Main process only: remove Snakemake lock files left by dead runs; return the open flock
    file, which must stay open (and so locked, shared) until this process exits."""
    if not workflow.is_main_process:
        return None
    snakemake_dir.mkdir(parents=True, exist_ok=True)
    fh = open(snakemake_dir / "gmwm-run.flock", "a")
    locks = snakemake_dir / "locks"
    if _flock_exclusive(fh, wait_s):
        if locks.is_dir() and any(locks.iterdir()):
            shutil.rmtree(locks)
            logger.warning(f"removed stale Snakemake locks of a killed run in {Path.cwd()}")
    elif locks.is_dir() and any(locks.iterdir()):
        logger.info("another Snakemake process uses this directory (it holds "
                    f"{snakemake_dir}/gmwm-run.flock): its locks are kept")
    fcntl.flock(fh, fcntl.LOCK_SH)  # downgrade (or take) the shared flock for this process's life
    return fh


_RUN_FLOCK = clear_stale_locks()
