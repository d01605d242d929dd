"""CAN frames into a run's recording (run.mcap's `/can` channel), decoded by the chassis profile's DBC.

A can.Listener on the bridge: every frame it sends or receives is added with its DBC signals (named enum
values as strings; none for an ID the DBC does not hold) at the chassis time the bridge gives it.
"""

from __future__ import annotations

from collections.abc import Callable

import can
from cantools.database.can import Database

from testbed.eval.run.recording import Recording


class CanToRecording(can.Listener):
    """Feeds `recording.add_can`; `clock` is the chassis time (s) to stamp each frame with."""

    def __init__(self, recording: Recording, db: Database, clock: Callable[[], float]) -> None:
        self.recording = recording
        self.db = db
        self.clock = clock
        self.frames = 0

    def on_message_received(self, msg: can.Message) -> None:
        try:
            decoded = self.db.decode_message(msg.arbitration_id, bytes(msg.data), decode_choices=True)
        except (KeyError, ValueError):  # an ID the DBC does not hold, or a payload it cannot decode
            decoded = {}
        self.recording.add_can(self.clock(), msg.arbitration_id, bytes(msg.data), decoded)
        self.frames += 1
