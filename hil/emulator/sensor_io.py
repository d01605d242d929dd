"""Sensor-level HIL (`ld3 hil SCENARIO --sensors io`): the simulated GNSS goes out as NMEA GGA on a pty and
comes back through the NMEA reader, the rendered camera frames through the camera reader, so the loop sees
its sensors exactly as on a vehicle, readers, timing and failure handling included. A stalled stream
(`gnss_stalled`, `camera_stalled`) is a fault of the run.

Each sensor sample waits (up to `reply_s`) for its own round trip, so a lockstep run stays in step with its
readers; `silence_gnss` and `drop_camera` stop a stream from a chassis time on, as a failing receiver or camera
would.
"""

from __future__ import annotations

import contextlib
import math
import os
import tty
from collections.abc import Callable

from hil.vehicle.camera_reader import CameraReader, HandedFrames
from hil.vehicle.geodetic import DEFAULT_ORIGIN, LocalTangentPlane
from hil.vehicle.nmea_gnss import NmeaGnssReader, open_nmea
from hil.vehicle.nmea_out import gga_sentence
from testbed.errors import UserError
from testbed.lane_detection import CameraFrame
from testbed.localization.sensors import GnssFix
from testbed.loop import SensorPorts
from tracks.pose import Pose

SENSOR_MODES = ("sim", "io")
REPLY_S = 0.5

Capture = Callable[[float, Pose | None], CameraFrame]


class SensorIo:
    """The NMEA pty and reader and the camera reader of one run; `wrap` routes a run's sensor ports through
    them; `on_fault(kind, detail)` is told of a stall; `clock` is the loop's time base."""

    def __init__(self, clock: Callable[[], float], on_fault: Callable[[str, str], None],
                 plane: LocalTangentPlane | None = None, reply_s: float = REPLY_S) -> None:
        plane = plane or LocalTangentPlane(*DEFAULT_ORIGIN)
        self.plane = plane
        self.on_fault = on_fault
        self.reply_s = reply_s
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.tty_path = os.ttyname(self._slave)
        self.gnss = NmeaGnssReader(open_nmea(self.tty_path), plane, clock)
        self._frames = HandedFrames()
        self.camera = CameraReader(self._frames, clock)
        self._sent_frames = 0
        self.gnss_silent_from = math.inf
        self.camera_dropped_from = math.inf

    def silence_gnss(self, t: float) -> None:
        """From chassis time `t` on, no NMEA goes out (a receiver that stops)."""
        self.gnss_silent_from = t

    def drop_camera(self, t: float) -> None:
        """From chassis time `t` on, no frame reaches the reader (a camera that stops)."""
        self.camera_dropped_from = t

    def wrap(self, ports: SensorPorts) -> SensorPorts:
        localization = ports.localization
        if not hasattr(localization, "gnss_port"):
            raise UserError("--sensors io sends the simulated GNSS as NMEA: it needs --localization msf")
        localization.gnss_port = self._gnss
        return SensorPorts(localization, self._camera(ports.camera) if ports.camera is not None else None)

    def _gnss(self, fix: GnssFix) -> GnssFix | None:
        sent = fix.t < self.gnss_silent_from
        if sent:
            os.write(self._master, gga_sentence(fix, self.plane))
        fixes = self.gnss.take(self.reply_s if sent else 0.0)
        if fixes:
            return fixes[-1]
        why = self.gnss.stalled(fix.t)
        if why is not None:
            self.on_fault("gnss_stalled", why)
        return None

    def _camera(self, render: Capture) -> Capture:
        def capture(t: float, pose: Pose | None) -> CameraFrame:
            frame = render(t, pose)
            if t < self.camera_dropped_from:
                self._frames.put(frame.image)
                self._sent_frames += 1
                self.camera.wait_frame(self._sent_frames, self.reply_s)
            got = self.camera.capture(t, pose)
            if got.image is None and (why := self.camera.stalled(t)) is not None:
                self.on_fault("camera_stalled", why)
            return got

        return capture

    def counts(self) -> dict[str, int]:
        c = self.gnss.counts
        return {"nmea_fixes": c.fixes, "nmea_bad": c.bad, "nmea_no_fix": c.no_fix, "camera_frames": self.camera.frames}

    def close(self) -> None:
        self.camera.close()
        self.gnss.close()
        with contextlib.suppress(OSError):
            self.gnss.stream.close()
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
