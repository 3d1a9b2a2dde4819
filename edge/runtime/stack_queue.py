"""Bounded hand-over between capture and decoding that never blocks the capture side.

`put` always succeeds at once: when the queue is full the OLDEST whole stack is discarded and
counted as stale, so the decoder always works on the freshest data and capture never waits.
Items are whole `Stack` objects, so frames of two stacks can never be mixed.
"""

from __future__ import annotations

import collections
import threading
from typing import Generic, TypeVar

T = TypeVar("T")


class Closed(Exception):
    """`LatestQueue.get` on a closed, drained queue."""


class LatestQueue(Generic[T]):
    """A drop-oldest bounded queue.  capacity >= 1; `dropped` counts discarded items."""

    def __init__(self, capacity: int = 2) -> None:
        if capacity < 1:
            raise ValueError(f"queue capacity must be >= 1, got {capacity}")
        self.capacity = int(capacity)
        self._items: collections.deque[T] = collections.deque()
        self._cond = threading.Condition()
        self._closed = False
        self.dropped = 0
        self.put_count = 0

    def put(self, item: T) -> T | None:
        """Append ``item``; returns the stale item that was dropped to make room, if any."""
        with self._cond:
            if self._closed:
                raise Closed("queue is closed")
            stale = None
            if len(self._items) >= self.capacity:
                stale = self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            self.put_count += 1
            self._cond.notify()
            return stale

    def get(self, timeout_s: float | None = None) -> T | None:
        """Oldest item, waiting up to ``timeout_s``; None on timeout; `Closed` when closed and empty."""
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait(timeout_s)
            if self._items:
                return self._items.popleft()
            if self._closed:
                raise Closed("queue is closed")
            return None

    def discard(self) -> int:
        """Drop everything queued (a stopping service does not decode it); returns how many."""
        with self._cond:
            n = len(self._items)
            self._items.clear()
            return n

    def close(self) -> None:
        """No more puts; getters drain what is left, then get `Closed`."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)
