"""Readers of recordings and shared tables; each checks its input at the boundary and raises
:class:`gmwm.errors.InputError` with a one-line message naming the problem."""

from gmwm.readers.recording import Recording, imu_topics, read_recording, read_recordings
from gmwm.readers.tables import (
    MIN_TABLE_SIGNAL,
    SIGNAL_SUFFIXES,
    Channels,
    is_wv_table,
    read_channels,
    read_signal,
    read_weights,
    read_wv_table,
    table_channels,
    time_column_unit,
)

__all__ = [
    "MIN_TABLE_SIGNAL",
    "SIGNAL_SUFFIXES",
    "Channels",
    "Recording",
    "imu_topics",
    "is_wv_table",
    "read_channels",
    "read_recording",
    "read_recordings",
    "read_signal",
    "read_weights",
    "read_wv_table",
    "table_channels",
    "time_column_unit",
]
