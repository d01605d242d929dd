"""The adapter side of an SLCAN serial link on a pseudo-terminal, as a python-can bus.

`SlcanPtyBus` opens a pty pair and speaks the SLCAN ASCII protocol of common USB-CAN adapters on the master
side: it answers the host's O/L/C/S<n>/s<btr>/V/v/N/F/Z commands with CR (ok) or BEL (error), turns host
t/T/r/R lines into received frames (answering z/Z), and writes frames it sends as t<id><dlc><data>CR while the
host has the channel open. The host
opens the slave path with python-can's slcan interface: can.Bus(interface="slcan", channel=bus.tty_path).
"""

from __future__ import annotations

import contextlib
import os
import select
import time
import tty
from collections import deque

import can

_VERSION_REPLY = b"V1013\r"
_SERIAL_REPLY = b"NLD3E\r"


class SlcanPtyBus(can.BusABC):
    """A CAN bus whose only peer is the SLCAN host on the pty slave `tty_path`."""

    def __init__(self, channel: str | None = None, **kwargs: object) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.tty_path = os.ttyname(self._slave)
        self.channel_info = f"SLCAN on {self.tty_path}"
        self._buffer = bytearray()
        self._frames: deque[can.Message] = deque()
        self.is_open = False
        self.errors = 0
        self.dropped = 0
        super().__init__(channel=channel or self.tty_path, **kwargs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Forward `msg` to the host; while the host has its channel closed (before O, after C) the frame is
        dropped and counted in `dropped`, as an adapter forwards nothing to a closed channel."""
        if not self.is_open:
            self.dropped += 1
            return
        data = bytes(msg.data)[: msg.dlc].hex().upper()
        if msg.is_extended_id:
            line = f"{'R' if msg.is_remote_frame else 'T'}{msg.arbitration_id:08X}{msg.dlc:d}"
        else:
            line = f"{'r' if msg.is_remote_frame else 't'}{msg.arbitration_id:03X}{msg.dlc:d}"
        if not msg.is_remote_frame:
            line += data
        self._write(line.encode() + b"\r")

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            written = os.write(self._master, view)
            view = view[written:]

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        while True:
            self._parse_lines()
            if self._frames:
                return self._frames.popleft(), False
            ready, _, _ = select.select([self._master], [], [], timeout)
            if not ready:
                return None, False
            try:
                chunk = os.read(self._master, 4096)
            except OSError:
                return None, False
            self._buffer.extend(chunk)
            timeout = 0.0

    def _parse_lines(self) -> None:
        while True:
            end = self._buffer.find(b"\r")
            if end < 0:
                return
            line = bytes(self._buffer[:end]).decode("ascii", errors="replace")
            del self._buffer[: end + 1]
            self._write(self._answer(line))

    def _answer(self, line: str) -> bytes:
        if not line:
            return b"\r"
        command = line[0]
        if command in "OL":
            self.is_open = True
            return b"\r"
        if command == "C":
            self.is_open = False
            return b"\r"
        if command in "SsZF":
            return b"F00\r" if command == "F" else b"\r"
        if command == "V":
            return _VERSION_REPLY
        if command == "N":
            return _SERIAL_REPLY
        if command in "tTrR" and self.is_open:
            frame = self._parse_frame(line)
            if frame is not None:
                self._frames.append(frame)
                return b"Z\r" if command in "TR" else b"z\r"
        self.errors += 1
        return b"\a"

    @staticmethod
    def _parse_frame(line: str) -> can.Message | None:
        extended = line[0] in "TR"
        remote = line[0] in "rR"
        id_len = 8 if extended else 3
        try:
            arbitration_id = int(line[1 : 1 + id_len], 16)
            dlc = int(line[1 + id_len], 16)
            payload = "" if remote else line[2 + id_len :]
            data = bytes.fromhex(payload)
        except (ValueError, IndexError):
            return None
        if dlc > 8 or (not remote and len(data) != dlc) or arbitration_id >= (1 << (29 if extended else 11)):
            return None
        return can.Message(
            arbitration_id=arbitration_id,
            is_extended_id=extended,
            is_remote_frame=remote,
            dlc=dlc,
            data=b"" if remote else data,
            timestamp=time.time(),
        )

    def shutdown(self) -> None:
        super().shutdown()
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
