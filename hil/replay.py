"""Replay of a recorded CAN log (.asc or .blf) onto a bus, paced by its timestamps via can.MessageSync."""

from __future__ import annotations

from pathlib import Path

import can


def replay_log(path: Path, bus: can.BusABC, realtime: bool = True) -> int:
    """Send every frame of `path` onto `bus` (with the recorded gaps if `realtime`); returns the count."""
    count = 0
    with can.LogReader(str(path)) as reader:
        frames = can.MessageSync(reader, timestamps=True, skip=3600.0) if realtime else reader
        for frame in frames:
            if frame.is_error_frame:
                continue
            bus.send(frame)
            count += 1
    return count
