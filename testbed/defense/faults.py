"""Bad-input bookkeeping for a defense: each fault is logged (python logging) and counted.

The first occurrence of a fault kind after a clean update logs a warning, repeats log at debug level,
so a long off-map stretch does not flood the log.
"""

from __future__ import annotations

import logging
from collections import Counter


class FaultLog:
    """Counts faults per kind and logs them without flooding."""

    def __init__(self, logger: logging.Logger) -> None:
        self._logger = logger
        self.counts: Counter[str] = Counter()
        self._active: set[str] = set()

    def report(self, kind: str, t: float, detail: str) -> None:
        self.counts[kind] += 1
        level = logging.DEBUG if kind in self._active else logging.WARNING
        self._active.add(kind)
        self._logger.log(level, "t=%.3f %s: %s", t, kind, detail)

    def clear(self) -> None:
        """A clean update: the next fault of any kind warns again."""
        self._active.clear()
