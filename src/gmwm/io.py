"""The names ``gmwm.cli`` still imports from here; readers live in :mod:`gmwm.readers`, atomic
writers in :mod:`gmwm.atomic`, lossless result files in :mod:`gmwm.codec`."""

# temporary: cli.py is being rewritten
from gmwm.atomic import save_figure, to_jsonable, write_signal, write_text_atomic
from gmwm.readers.tables import (
    SIGNAL_SUFFIXES,
    is_wv_table,
    read_channels,
    read_wv_table,
    table_channels,
)

__all__ = ["SIGNAL_SUFFIXES", "is_wv_table", "read_channels", "read_wv_table", "save_figure",
           "table_channels", "to_jsonable", "write_signal", "write_text_atomic"]
