"""Logging for workflow scripts: messages go to the rule's log file (and stderr)."""

import logging
import sys


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
