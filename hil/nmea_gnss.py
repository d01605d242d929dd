"""GNSS from an NMEA 0183 stream (a serial device, a pty, a file): GGA sentences parsed by pynmeagps become
`GnssFix`es in the map's world frame, stamped with the reader's clock on arrival.

The fix's covariance is the receiver's HDOP times the user-equivalent range error of its fix quality
(`UERE_M`); a sentence with a bad checksum or without a fix (quality 0, 6 estimated, 7 manual, 8 simulation)
is counted and fuses nothing. No accepted fix for `stall_s` is a stall (`stalled`), which the run reports as a
fault rather than drive on without GNSS.
"""

from __future__ import annotations

import os
import stat
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np
import serial
from pynmeagps import NMEAMessage, NMEAParseError, NMEAReader

from hil.geodetic import LocalTangentPlane
from testbed.localization.sensors import GnssFix

UERE_M = {1: 2.5, 2: 0.7, 4: 0.02, 5: 0.25, 9: 1.0}
"""1-σ horizontal range error (m) per unit HDOP by GGA fix quality: 1 autonomous GPS, 2 DGPS, 4 RTK fixed,
5 RTK float, 9 SBAS (WAAS/EGNOS). Other qualities are not fixes the MSF may fuse."""
DEFAULT_STALL_S = 1.0


def fix_covariance(quality: int, hdop: float) -> np.ndarray | None:
    """The 2×2 world-frame covariance of a fix of GGA `quality` and `hdop`; None where it is no usable fix."""
    uere = UERE_M.get(quality)
    if uere is None or not hdop > 0.0:
        return None
    std = uere * hdop
    return np.eye(2) * std * std


@dataclass
class NmeaCounts:
    """What the reader saw: fixes accepted, sentences with a bad checksum or unparsable, GGA without a fix."""

    fixes: int = 0
    bad: int = 0
    no_fix: int = 0


class NmeaGnssReader:
    """Reads NMEA from `stream` on its own thread until it ends or `close()`; `take()` hands the loop every fix
    that arrived since the last call. `clock` stamps the fixes (the loop's time base)."""

    def __init__(self, stream: BinaryIO, plane: LocalTangentPlane, clock: Callable[[], float],
                 stall_s: float = DEFAULT_STALL_S) -> None:
        self.stream = stream
        self.plane = plane
        self.clock = clock
        self.stall_s = stall_s
        self.counts = NmeaCounts()
        self.last_fix_t: float | None = None
        self.ended: str | None = None
        """Why the stream ended (EOF or the error), None while it runs."""
        self._fixes: deque[GnssFix] = deque()
        self._arrived = threading.Condition()
        self._stop = threading.Event()
        self._started_t = clock()
        self._thread = threading.Thread(target=self._read, name="nmea-gnss", daemon=True)
        self._thread.start()

    def take(self, wait_s: float = 0.0) -> list[GnssFix]:
        """Fixes that arrived since the last call, oldest first; waits up to `wait_s` for one if none has."""
        with self._arrived:
            if not self._fixes and wait_s > 0.0:
                self._arrived.wait(wait_s)
            fixes = list(self._fixes)
            self._fixes.clear()
        return fixes

    def stalled(self, now: float) -> str | None:
        """Why GNSS counts as stalled at `now` (no fix for stall_s, the stream ended), else None."""
        last = self.last_fix_t if self.last_fix_t is not None else self._started_t
        if now - last <= self.stall_s:
            return None
        c = self.counts
        why = f"no GNSS fix for {now - last:.1f} s ({c.fixes} fixes, {c.bad} bad sentences, {c.no_fix} without fix)"
        return f"{why}; stream ended: {self.ended}" if self.ended else why

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)

    def _read(self) -> None:
        try:
            for line in self._lines():
                self.handle(line)
            self.ended = "end of stream"
        except (OSError, ValueError) as exc:  # a closed or vanished device
            self.ended = " ".join(str(exc).split()) or type(exc).__name__

    def _lines(self) -> Iterator[bytes]:
        """Complete lines as they arrive; a serial port's read time-out is not an end, a file's empty read is."""
        serial_port = hasattr(self.stream, "in_waiting")
        buffer = b""
        while not self._stop.is_set():
            chunk = self.stream.read(1)
            if not chunk:
                if serial_port:
                    continue
                return
            if serial_port and self.stream.in_waiting:
                chunk += self.stream.read(self.stream.in_waiting)
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            for line in lines:
                yield line + b"\n"

    def handle(self, line: bytes) -> GnssFix | None:
        """Parse one sentence; a GGA with a usable fix is queued for `take` and returned."""
        if not line.strip().startswith(b"$"):
            return None
        try:
            message = NMEAReader.parse(line.strip() + b"\r\n")
        except NMEAParseError:
            self.counts.bad += 1
            return None
        if message is None or message.msgID != "GGA":
            return None
        fix = self._fix(message)
        if fix is None:
            self.counts.no_fix += 1
            return None
        self.counts.fixes += 1
        with self._arrived:
            self.last_fix_t = fix.t
            self._fixes.append(fix)
            self._arrived.notify_all()
        return fix

    def _fix(self, gga: NMEAMessage) -> GnssFix | None:
        try:
            quality, hdop, lat, lon = int(gga.quality), float(gga.HDOP), float(gga.lat), float(gga.lon)
        except (TypeError, ValueError):
            return None
        cov = fix_covariance(quality, hdop)
        if cov is None:
            return None
        return GnssFix(self.clock(), np.array(self.plane.to_xy(lat, lon)), cov)


def open_nmea(path: str, baudrate: int = 115_200) -> BinaryIO:
    """The NMEA stream at `path`: a serial device or pty (pyserial, 0.1 s read time-out) or a regular file."""
    if stat.S_ISCHR(os.stat(path).st_mode):
        return serial.Serial(path, baudrate=baudrate, timeout=0.1)
    return open(path, "rb")
