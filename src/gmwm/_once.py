"""A memo that threads share, computing each key once (``gmwm.plan`` fills the WV-covariance
memo and its prediction cache from several threads)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable
from typing import Any


class OnceMemo:
    """Values by key; a key asked for while another thread computes it waits for that
    computation rather than repeating it, and computes it itself if that one failed (the failure
    is raised in the thread that hit it). ``size``: keep at most that many, the oldest dropped
    first (None: all)."""

    def __init__(self, size: int | None = None) -> None:
        self.size = size
        self._store: dict[Hashable, Any] = {}
        self._busy: dict[Hashable, threading.Event] = {}
        self._lock = threading.Lock()

    def get(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """The value of ``key``, from ``compute()`` the first time (one thread at a time)."""
        while True:
            with self._lock:
                if key in self._store:
                    return self._store[key]
                busy = self._busy.get(key)
                if busy is None:
                    busy = self._busy[key] = threading.Event()
                    break
            busy.wait()  # if that computation failed, the next round does it here
        try:
            value = compute()
            with self._lock:
                if self.size is not None and len(self._store) >= self.size:
                    self._store.pop(next(iter(self._store)))  # the oldest
                self._store[key] = value
        finally:
            with self._lock:
                del self._busy[key]
            busy.set()
        return value

    @property
    def computing(self) -> bool:
        """Whether a computation is under way."""
        with self._lock:
            return bool(self._busy)

    def clear(self) -> None:
        with self._lock:
            self._store.clear()

    def __len__(self) -> int:
        return len(self._store)
