"""Replay of a recorded CAN log (.asc or .blf) onto a bus, paced by its timestamps via can.MessageSync (a
lockstep log carries plant time, so it replays at the plant's pace)."""

from __future__ import annotations

from pathlib import Path

import can


def replay_log(path: Path, bus: can.BusABC, realtime: bool = True, ids: frozenset[int] | None = None) -> int:
    """Send the frames of `path` whose ID is in `ids` (None: all) onto `bus`, with the recorded gaps between
    them if `realtime`; returns the count."""
    count = 0
    with can.LogReader(str(path)) as reader:
        chosen = (f for f in reader if not f.is_error_frame and (ids is None or f.arbitration_id in ids))
        frames = can.MessageSync(chosen, timestamps=True, skip=3600.0) if realtime else chosen
        for frame in frames:
            bus.send(frame)
            count += 1
    return count
