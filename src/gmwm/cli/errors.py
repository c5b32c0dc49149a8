"""Library errors as the command line says them: the one mapping from library parameter names to
the flags that set them.

The library names the parameter a message is about in backquotes (``give `freq` (Hz)``), so a
Python caller reads the argument to pass; the command-line tool prints the same message with the
flag instead (``give --freq (Hz)``) through :func:`as_flags`, applied where it prints a library
error. A backquoted word that is no parameter here (a column or model name) stays as it is.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

#: library parameter name (or function, for the identifiability check) -> the flag that sets it
PARAMETER_FLAGS: Mapping[str, str] = {
    "freq": "--freq",
    "units": "--units",
    "unit": "--units",
    "column": "--column",
    "columns": "--columns",
    "dataset": "--dataset",
    "dtype": "--dtype",
    "topic": "--topic",
    "topics": "--topic",
    "rostopic": "--rostopic",
    "time_unit": "--time-unit",
    "n_samples": "--n-samples",
    "start_s": "--start",
    "end_s": "--end",
    "segment": "--segment",
    "strict": "--strict",
    "allow_motion": "--allow-motion",
    "motion_share": "--motion-share",
    "gaps": "--gaps",
    "sheet": "--datasheet",
    "levels": "--levels",
    "method": "--method",
    "robust": "--robust",
    "gmwm.identify.check": "--check",
}

_PARAMETER = re.compile(r"`([A-Za-z_][A-Za-z0-9_.]*)`")


def as_flags(message: str) -> str:
    """``message`` (of a library error) with every backquoted parameter of
    :data:`PARAMETER_FLAGS` replaced by its flag: ``"`start_s`/`end_s` select 0 samples"`` ->
    ``"--start/--end select 0 samples"``."""
    return _PARAMETER.sub(lambda m: PARAMETER_FLAGS.get(m.group(1), m.group(0)), message)
