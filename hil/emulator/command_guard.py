"""ECU-side admission of command frames: verification, rejection counts, bad-run and foreign-node faults.

A frame on a command ID is admitted only if the codec verifies it (format, checksum, range, life
counter; freshness and MAC where the profile secures the ID). `run_limit` consecutive rejections on one ID
latch the bad-frames fault; more than `max_per_window` frames on one command ID within `window_s` (two
senders doubling the 50 Hz rate) latch the foreign-node fault. Faults stay latched until `clear_faults`;
counts are cumulative.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import can

from hil.link.codec import REJECT_REASONS, ChassisCodec, DecodedFrame, FrameRejected


@dataclass(frozen=True)
class GuardLimits:
    """Thresholds of the command guard."""

    run_limit: int = 3
    window_s: float = 0.1
    max_per_window: int = 7


class CommandGuard:
    """Admits verified command frames and keeps the rejection counts and latched communication faults."""

    def __init__(self, codec: ChassisCodec, limits: GuardLimits = GuardLimits()) -> None:
        self._codec = codec
        self._limits = limits
        self.command_ids = frozenset(codec.frame_id(name) for name in codec.profile.commands.messages)
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.admitted = 0
        self.bad_frames = False
        self.foreign_node = False
        self._run = dict.fromkeys(self.command_ids, 0)
        self._arrivals: dict[int, deque[float]] = {i: deque() for i in self.command_ids}

    def admit(self, frame: can.Message, now: float) -> DecodedFrame | None:
        """The decoded frame if it is a valid command frame, else None (other IDs are left alone)."""
        frame_id = frame.arbitration_id
        if frame_id not in self.command_ids or frame.is_extended_id:
            return None
        self._note_arrival(frame_id, now)
        try:
            decoded = self._codec.decode(frame)
        except FrameRejected as rejection:
            self.rejected[rejection.reason] += 1
            self._run[frame_id] += 1
            if self._run[frame_id] >= self._limits.run_limit:
                self.bad_frames = True
            return None
        self._run[frame_id] = 0
        self.admitted += 1
        return decoded

    def _note_arrival(self, frame_id: int, now: float) -> None:
        arrivals = self._arrivals[frame_id]
        arrivals.append(now)
        while arrivals and arrivals[0] <= now - self._limits.window_s:
            arrivals.popleft()
        if len(arrivals) > self._limits.max_per_window:
            self.foreign_node = True

    def clear_faults(self) -> None:
        self.bad_frames = False
        self.foreign_node = False
        for frame_id in self.command_ids:
            self._run[frame_id] = 0
            self._arrivals[frame_id].clear()
