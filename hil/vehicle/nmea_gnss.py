"""GNSS from an NMEA 0183 stream (a serial device, a pty, a file): GGA sentences parsed by pynmeagps become
`GnssFix`es in the map's world frame, stamped with the reader's clock on arrival.

The fix's covariance is the receiver's HDOP times the user-equivalent range error of its fix quality
(`UERE_M`); a sentence with a bad checksum or without a fix (quality 0, 6 estimated, 7 manual, 8 simulation)
is counted and fuses nothing. A sentence with a valid checksum is still refused, and counted by reason, when
its HDOP is not a number in [MIN_HDOP, MAX_HDOP], its position is not a finite latitude/longitude with N/S and
E/W within MAX_RANGE_M of the map's origin, or its UTC time is missing or not after the last accepted fix's.
No accepted fix for `stall_s`, or MAX_REFUSED_RUN bad or refused sentences in a row, is a fault (`stalled`),
which the run reports rather than drive on without GNSS. A regular file plays at its sentences' UTC times
(each GGA is handed over when as much wall time has passed since the first as UTC time has).
"""

from __future__ import annotations

import datetime
import math
import os
import stat
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import BinaryIO

import numpy as np
import serial
from pynmeagps import NMEAMessage, NMEAParseError, NMEAReader

from hil.vehicle.geodetic import LocalTangentPlane
from testbed.localization.sensors import GnssFix

UERE_M = {1: 2.5, 2: 0.7, 4: 0.02, 5: 0.25, 9: 1.0}
"""1-σ horizontal range error (m) per unit HDOP by GGA fix quality: 1 autonomous GPS, 2 DGPS, 4 RTK fixed,
5 RTK float, 9 SBAS (WAAS/EGNOS). Other qualities are not fixes the MSF may fuse."""
DEFAULT_STALL_S = 1.0
MIN_HDOP, MAX_HDOP = 0.01, 99.0
"""HDOP a GGA can carry for a usable fix: two decimals at least 0.01; 99.99 is the conventional 'unknown'."""
MAX_RANGE_M = 100_000.0
"""A fix farther than this from the map's origin is no position on the map."""
MAX_REFUSED_RUN = 10
DAY_S = 86_400.0
REFUSAL_REASONS = ("hdop", "position", "time")


def fix_covariance(quality: int, hdop: float) -> np.ndarray | None:
    """The 2×2 world-frame covariance of a fix of GGA `quality` and `hdop`; None where it is no usable fix."""
    uere = UERE_M.get(quality)
    if uere is None or not hdop > 0.0:
        return None
    std = uere * hdop
    return np.eye(2) * std * std


@dataclass
class NmeaCounts:
    """What the reader saw: fixes accepted, lines with a bad checksum, unparsable or not NMEA, GGA without a fix,
    and GGA refused by reason (`REFUSAL_REASONS`)."""

    fixes: int = 0
    bad: int = 0
    no_fix: int = 0
    refused: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REFUSAL_REASONS, 0))

    def describe(self) -> str:
        refused = ", ".join(f"{n} {reason}" for reason, n in self.refused.items() if n) or "none"
        return f"{self.fixes} fixes, {self.bad} bad sentences, {self.no_fix} without fix, refused: {refused}"


def seconds_of_day(value: object) -> float | None:
    """A GGA time field (pynmeagps: datetime.time, '' when missing or invalid) as seconds after midnight UTC."""
    if not isinstance(value, datetime.time):
        return None
    return value.hour * 3600.0 + value.minute * 60.0 + value.second + value.microsecond / 1e6


def _after(t: float, last: float) -> bool:
    """UTC time of day `t` is later than `last` (across midnight when `last` is in the day's last hour)."""
    return t > last or (last > DAY_S - 3600.0 and t < 3600.0)


class NmeaGnssReader:
    """Reads NMEA from `stream` on its own thread until it ends or `close()`; `take()` hands the loop every fix
    that arrived since the last call. `clock` stamps the fixes (the loop's time base). `paced` (default: the
    stream is a regular file) plays the sentences at their UTC times on `wall` (a monotonic clock)."""

    def __init__(self, stream: BinaryIO, plane: LocalTangentPlane, clock: Callable[[], float],
                 stall_s: float = DEFAULT_STALL_S, paced: bool | None = None,
                 wall: Callable[[], float] = time.monotonic) -> None:
        self.stream = stream
        self.plane = plane
        self.clock = clock
        self.stall_s = stall_s
        self.paced = _regular_file(stream) if paced is None else paced
        self._wall = wall
        self._first: tuple[float, float] | None = None  # (UTC seconds of day, wall time) of the first paced fix
        self._last_utc: float | None = None
        self._refused_run = 0
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
        """Why GNSS counts as failed at `now` (no fix for stall_s, the stream ended, a run of bad or refused
        sentences), else None."""
        if self._refused_run >= MAX_REFUSED_RUN:
            return f"{self._refused_run} bad or refused NMEA sentences in a row ({self.counts.describe()})"
        last = self.last_fix_t if self.last_fix_t is not None else self._started_t
        if now - last <= self.stall_s:
            return None
        why = f"no GNSS fix for {now - last:.1f} s ({self.counts.describe()})"
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
        if not line.strip():
            return None
        if not line.strip().startswith(b"$"):
            return self._bad()
        try:
            message = NMEAReader.parse(line.strip() + b"\r\n")
        except NMEAParseError:
            return self._bad()
        if message is None or message.msgID != "GGA":
            return None
        try:
            quality = int(message.quality)
        except (TypeError, ValueError):
            return self._bad()
        if quality not in UERE_M:
            self.counts.no_fix += 1
            return None
        refusal, utc, xy, hdop = self._check(message)
        if refusal is not None:
            self.counts.refused[refusal] += 1
            self._refused_run += 1
            return None
        assert utc is not None and xy is not None
        self._pace(utc)
        cov = fix_covariance(quality, hdop)
        assert cov is not None
        fix = GnssFix(self.clock(), xy, cov)
        self.counts.fixes += 1
        self._refused_run = 0
        self._last_utc = utc
        with self._arrived:
            self.last_fix_t = fix.t
            self._fixes.append(fix)
            self._arrived.notify_all()
        return fix

    def _bad(self) -> None:
        self.counts.bad += 1
        self._refused_run += 1

    def _check(self, gga: NMEAMessage) -> tuple[str | None, float | None, np.ndarray | None, float]:
        """(refusal reason or None, UTC seconds of day, world position, HDOP) of a GGA that reports a fix."""
        hdop = _number(gga.HDOP)
        if not MIN_HDOP <= hdop <= MAX_HDOP:
            return "hdop", None, None, hdop
        lat, lon = _number(gga.lat), _number(gga.lon)
        if not (abs(lat) <= 90.0 and abs(lon) <= 180.0 and gga.NS in ("N", "S") and gga.EW in ("E", "W")):
            return "position", None, None, hdop
        xy = np.array(self.plane.to_xy(lat, lon))
        if not (np.all(np.isfinite(xy)) and math.hypot(*xy) <= MAX_RANGE_M):
            return "position", None, None, hdop
        utc = seconds_of_day(gga.time)
        if utc is None or (self._last_utc is not None and not _after(utc, self._last_utc)):
            return "time", None, None, hdop
        return None, utc, xy, hdop

    def _pace(self, utc: float) -> None:
        """Paced streams: wait until as much wall time has passed since the first fix as UTC time has."""
        if not self.paced:
            return
        if self._first is None:
            self._first = (utc, self._wall())
            return
        utc0, wall0 = self._first
        delay = wall0 + (utc - utc0) % DAY_S - self._wall()
        if delay > 0:
            self._stop.wait(delay)


def _number(value: object) -> float:
    """A numeric NMEA field as a float; NaN where it is empty or no number."""
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan


def _regular_file(stream: BinaryIO) -> bool:
    try:
        return stat.S_ISREG(os.fstat(stream.fileno()).st_mode)
    except (OSError, ValueError, AttributeError):  # io.BytesIO and other streams without a descriptor
        return False


def open_nmea(path: str, baudrate: int = 115_200) -> BinaryIO:
    """The NMEA stream at `path`: a serial device or pty (pyserial, 0.1 s read time-out) or a regular file."""
    if stat.S_ISCHR(os.stat(path).st_mode):
        return serial.Serial(path, baudrate=baudrate, timeout=0.1)
    return open(path, "rb")
