"""Report-rate guard: a token bucket per report ID that tells a second sender from a starved receive thread.

Tokens accrue at (1 + DRIFT) per report cycle of wall time and each arrival spends one; a steady stream
holds `slack` tokens in reserve, the bucket holds at most twice that, and a frame that finds it empty is
over the rate. A receive thread starved for up to `slack` cycles is handed
the queued frames at once and spends exactly the tokens the stall accrued, so stalls never add up; a second
sender on the same ID spends one extra token per cycle and is caught within `slack` to 2 * `slack` cycles.
"""

from __future__ import annotations

import math

DRIFT = 0.01


class ReportRateGuard:
    """Per-ID token bucket over arrival times in seconds; `arrive` is False once an ID ran past its rate."""

    def __init__(self, ids: frozenset[int] | set[int], cycle_s: float, slack_cycles: float) -> None:
        if not (cycle_s > 0 and slack_cycles >= 1):
            raise ValueError(f"report rate guard needs cycle_s > 0 and slack_cycles >= 1: {cycle_s}, {slack_cycles}")
        self.cycle_s = cycle_s
        self.slack = float(slack_cycles)
        self._tokens = dict.fromkeys(ids, self.slack + 1.0)
        self._last: dict[int, float | None] = dict.fromkeys(ids)

    @classmethod
    def for_timeout(cls, ids: frozenset[int] | set[int], cycle_s: float, timeout_s: float) -> ReportRateGuard:
        """Tolerate a receive stall as long as the report time-out (which faults on its own beyond that)."""
        return cls(ids, cycle_s, max(math.ceil(timeout_s / cycle_s), 1))

    def arrive(self, frame_id: int, t: float) -> bool:
        """Count one frame of `frame_id` received at wall time `t`; False when it exceeds the rate."""
        last = self._last[frame_id]
        tokens = self._tokens[frame_id]
        if last is not None:
            tokens = min(tokens + max(t - last, 0.0) / self.cycle_s * (1.0 + DRIFT), 2.0 * self.slack + 1.0)
        self._last[frame_id] = t
        self._tokens[frame_id] = tokens - 1.0
        return tokens >= 1.0
