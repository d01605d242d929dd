"""Replay of a recorded CAN log (.asc or .blf) onto a bus, paced by its timestamps via can.MessageSync (a
lockstep log carries plant time, so it replays at the plant's pace). A gap longer than `MAX_GAP_S` in the log's
stamps is cut to that, so a log stamped hours ahead does not make the replay wait hours; a log python-can cannot
read is a one-line UserError naming it."""

from __future__ import annotations

from pathlib import Path

import can

from testbed.errors import UserError

MAX_GAP_S = 5.0


def replay_log(path: Path, bus: can.BusABC, realtime: bool = True, ids: frozenset[int] | None = None) -> int:
    """Send the frames of `path` whose ID is in `ids` (None: all) onto `bus`, with the recorded gaps between
    them if `realtime`; returns the count."""
    count = 0
    try:
        with can.LogReader(str(path)) as reader:
            chosen = (f for f in reader if not f.is_error_frame and (ids is None or f.arbitration_id in ids))
            frames = can.MessageSync(chosen, timestamps=True, skip=MAX_GAP_S) if realtime else chosen
            for frame in frames:
                bus.send(frame)
                count += 1
    except UserError:
        raise
    except Exception as exc:  # python-can's readers raise what their parsers raise on a garbled log
        problem = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
        raise UserError(f"{path}: not a readable CAN log ({problem}); {count} frames were sent") from None
    if count == 0:
        raise UserError(f"{path}: no CAN frames to replay (not a log python-can reads, or none of the chosen IDs)")
    return count
