"""Frame recorder: every frame a bridge sends and receives, written by can.Logger (.asc or .blf)."""

from __future__ import annotations

import copy
import threading
from pathlib import Path

import can

from testbed.errors import UserError

LOG_SUFFIXES = (".asc", ".blf")
RUN_LOG = "can.asc"
"""The CAN log's name in a run folder, as a run writes it and its summary names it."""


class FrameRecorder(can.Listener):
    """A thread-safe can.Listener writing to a can.Logger file; attach with CanChassisBridge.add_listener."""

    def __init__(self, path: Path) -> None:
        if path.suffix not in LOG_SUFFIXES:
            raise UserError(f"CAN log must end in {' or '.join(LOG_SUFFIXES)}: {path}")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.frames = 0
        self._lock = threading.Lock()
        self._logger = can.Logger(str(path))
        self._closed = False

    def on_message_received(self, msg: can.Message) -> None:
        with self._lock:
            if not self._closed:
                if not isinstance(msg.channel, int | None):  # BLF stores numeric channels only
                    msg = copy.copy(msg)
                    msg.channel = None
                self._logger.on_message_received(msg)
                self.frames += 1

    def stop(self) -> None:
        with self._lock:
            if not self._closed:
                self._closed = True
                self._logger.stop()
