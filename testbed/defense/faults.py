"""Bad-input bookkeeping for a defense: each fault is logged (python logging), counted and summarised.

The first occurrence of a fault kind after a clean update logs a warning, repeats log at debug level,
so a long off-map stretch does not flood the log. `records()` is what summary.json's `faults` lists for
the defense: per kind, the first time and detail, the last time and the count.
"""

from __future__ import annotations

import logging
from collections import Counter
from dataclasses import dataclass


@dataclass(frozen=True)
class FaultRecord:
    """One kind of fault a defense handled: its first occurrence (time, detail), last time and count."""

    kind: str
    time: float
    detail: str
    last_time: float
    count: int


class FaultLog:
    """Counts faults per kind and logs them without flooding."""

    def __init__(self, logger: logging.Logger) -> None:
        self._logger = logger
        self.counts: Counter[str] = Counter()
        self._active: set[str] = set()
        self._first: dict[str, tuple[float, str]] = {}
        self._last: dict[str, float] = {}

    def report(self, kind: str, t: float, detail: str, *, expected: bool = False) -> None:
        """Count one fault; `expected`: a consequence of a fault already warned of (logged at debug level)."""
        self.counts[kind] += 1
        self._first.setdefault(kind, (t, detail))
        self._last[kind] = t
        level = logging.DEBUG if expected or kind in self._active else logging.WARNING
        self._active.add(kind)
        self._logger.log(level, "t=%.3f %s: %s", t, kind, detail)

    def clear(self) -> None:
        """A clean update: the next fault of any kind warns again."""
        self._active.clear()

    def records(self) -> list[FaultRecord]:
        """One record per fault kind seen, in the order of their first occurrence."""
        return [FaultRecord(kind, t, detail, self._last[kind], self.counts[kind])
                for kind, (t, detail) in self._first.items()]
