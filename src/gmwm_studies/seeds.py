"""Reproducible per-replicate random streams for Monte Carlo studies.

Each replicate of a study draws from its own stream, keyed by (study name, sample size, replicate
index) under one global seed. A replicate's signal therefore does not depend on how replicates are
grouped into chunks, on the number of parallel jobs, or on the order in which jobs run.
"""

from __future__ import annotations

import zlib

import numpy as np

from gmwm.errors import InputError

__all__ = ["replicate_rng", "replicate_seed", "replicate_seed_sequence", "stable_int"]


def stable_int(name: str) -> int:
    """A 32-bit integer key of ``name`` that is identical across processes and Python versions.

    (Python's built-in ``hash`` of a str is salted per process, so it cannot key a stream.)
    """
    return zlib.crc32(name.encode("utf-8"))


def replicate_seed_sequence(
    study: str, n_samples: int, replicate: int, base_seed: int = 0, stream: int = 0
) -> np.random.SeedSequence:
    """The ``SeedSequence`` of one replicate: entropy ``base_seed``, spawn key (study, T, replicate).

    ``stream`` > 0 selects an independent stream of the same replicate for another purpose (e.g. the
    random starts of a fit) by appending it to the spawn key; stream 0 (the signal) uses the plain key.
    """
    checks = (("n_samples", n_samples), ("replicate", replicate), ("base_seed", base_seed),
              ("stream", stream))
    for label, value in checks:
        if int(value) != value or value < 0:
            raise InputError(f"{label} must be a non-negative integer, got {value!r}")
    key = (stable_int(study), int(n_samples), int(replicate))
    if stream:
        key += (int(stream),)
    return np.random.SeedSequence(entropy=int(base_seed), spawn_key=key)


def replicate_rng(
    study: str, n_samples: int, replicate: int, base_seed: int = 0
) -> np.random.Generator:
    """Generator (PCG64) for replicate ``replicate`` of ``study`` at sample size ``n_samples``."""
    return np.random.default_rng(replicate_seed_sequence(study, n_samples, replicate, base_seed))


def replicate_seed(study: str, n_samples: int, replicate: int, base_seed: int = 0,
                   stream: int = 1) -> int:
    """A 63-bit integer seed from stream ``stream`` of one replicate (for APIs taking an int seed)."""
    state = replicate_seed_sequence(study, n_samples, replicate, base_seed, stream).generate_state(
        1, np.uint64
    )
    return int(state[0] >> np.uint64(1))
