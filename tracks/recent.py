"""A bounded memo for pure queries asked again within a control tick."""

from __future__ import annotations

from typing import Generic, TypeVar

K = TypeVar("K")
V = TypeVar("V")


class RecentAnswers(dict[K, V], Generic[K, V]):
    """The answers to the last `size` distinct questions, the oldest dropped first."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.size = size

    def keep(self, key: K, answer: V) -> V:
        """Store `answer` for `key` (dropping the oldest beyond `size`) and return it."""
        self[key] = answer
        if len(self) > self.size:
            del self[next(iter(self))]
        return answer
