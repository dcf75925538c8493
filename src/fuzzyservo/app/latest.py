"""Run only the newest request: what keeps the page responsive while a slider moves.

A slider sends a new value many times a second. Queuing a run for each would leave the page
drawing the past for as long as the queue takes; instead :class:`Latest` runs one request at a
time in a worker thread, and a request that a newer one replaces before its run starts is
dropped, never run. A result whose request was replaced while it ran is not delivered either
(``deliver`` is told so), so the page never shows a run of settings that are no longer its
inputs, and once the inputs stop changing it shows the run of the last ones.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

__all__ = ["Latest", "LatestStats"]

Req = TypeVar("Req")
Res = TypeVar("Res")


@dataclass(frozen=True, slots=True)
class LatestStats:
    """Counts since the start: requests submitted, runs made, requests dropped before their
    run, and results dropped because a newer request came while they ran."""

    submitted: int
    ran: int
    dropped: int
    stale_results: int


class Latest(Generic[Req, Res]):
    """Run ``work`` on the newest of the submitted requests, one at a time.

    Parameters
    ----------
    work : callable
        ``work(request) -> result``; an exception it raises is the result (delivered as such).
    deliver : callable
        ``deliver(seq, result_or_exception)``, called in the worker thread with the request's
        sequence number (1, 2, ... in the order submitted) for each run whose request is still
        the newest when the run ends.
    """

    def __init__(self, work: Callable[[Req], Res],
                 deliver: Callable[[int, Res | BaseException], None]) -> None:
        self._work = work
        self._deliver = deliver
        self._lock = threading.Lock()
        self._pending: tuple[int, Req] | None = None
        self._busy = False
        self._seq = 0
        self._ran = 0
        self._dropped = 0
        self._stale = 0
        self._idle = threading.Event()
        self._idle.set()

    @property
    def newest(self) -> int:
        """Sequence number of the newest request submitted (0: none yet)."""
        return self._seq

    def stats(self) -> LatestStats:
        """The counts so far."""
        with self._lock:
            return LatestStats(self._seq, self._ran, self._dropped, self._stale)

    def submit(self, request: Req) -> int:
        """Make ``request`` the newest; returns its sequence number. A request still waiting
        for its run is dropped."""
        with self._lock:
            self._seq += 1
            if self._pending is not None:
                self._dropped += 1
            self._pending = (self._seq, request)
            start = not self._busy
            self._busy = True
            self._idle.clear()
            seq = self._seq
        if start:
            threading.Thread(target=self._loop, name="fuzzyservo-latest", daemon=True).start()
        return seq

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Wait until no request is waiting or running; False on timeout."""
        return self._idle.wait(timeout)

    def _loop(self) -> None:
        while True:
            with self._lock:
                if self._pending is None:
                    self._busy = False
                    self._idle.set()
                    return
                seq, request = self._pending
                self._pending = None
            result: Res | BaseException
            try:
                result = self._work(request)
            except Exception as exc:  # the page shows it as the CLI's one line
                result = exc
            with self._lock:
                self._ran += 1
                stale = self._seq != seq
                if stale:
                    self._stale += 1
            if not stale:
                self._deliver(seq, result)
