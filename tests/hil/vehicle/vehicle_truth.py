"""A vehicle on the bench with its GNSS from where it truly is: an in-process ECU emulator on a virtual bus
whose plant is a kinematic bicycle placed on a map lane, and a thread writing GGA at 10 Hz from the plant's
true pose onto a pty (with an HDOP of choice, as a hostile receiver would send, or pushed sideways, as a
spoofer would); `lane_video` writes what the camera sees of a straight lane from its centre."""

from __future__ import annotations

import itertools
import os
import threading
import time
import tty
import uuid
from pathlib import Path

import numpy as np
from pynmeagps import GET, NMEAMessage

from hil.emulator.ecu import EcuEmulator, EcuLimits
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bus_config import BusConfig
from hil.link.profile import load_profile
from hil.link.timing import ClockMode
from hil.link.wheels import WheelGeometry
from hil.vehicle.geodetic import DEFAULT_ORIGIN, LocalTangentPlane
from hil.vehicle.nmea_gnss import UERE_M
from testbed.presets import build_track, vehicle
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig

PLANE = LocalTangentPlane(*DEFAULT_ORIGIN)
RTK = 4


def gga(x: float, y: float, hdop: float) -> bytes:
    """One $GPGGA line at world (x, y) with `hdop` as given (RTK fix quality)."""
    lat, lon = PLANE.to_latlon(x, y)
    now = time.time()  # hundredths of a second: a 10 Hz stream's fixes each carry a later UTC time
    stamp = time.strftime("%H:%M:%S", time.gmtime(now)) + f".{int(now * 100) % 100:02d}"
    return NMEAMessage("GP", "GGA", GET, hpnmeamode=True, time=stamp, lat=abs(lat), NS="N" if lat >= 0 else "S",
                       lon=abs(lon), EW="E" if lon >= 0 else "W", quality=RTK, numSV=14, HDOP=hdop, alt=0.0,
                       altUnit="M", sep=0.0, sepUnit="M", diffAge="", diffStation="").serialize()


class TruthBench:
    """The ECU (profile folder `profile`) on virtual channel `channel`, its plant at `start_s` m of the `lane` of
    `track`; GGA from the plant's rear axle projected to the reference point, σ 0.05 m unless `hdop` is given
    (from `hostile_after` s of the feed on), pushed left at `push_mps` from `push_after` s after the car first
    moves. `off_lane_m()` is the plant's largest |lane deviation| so far."""

    def __init__(self, profile: str, track: str, start_s: float, lane: int = 0, vehicle_name: str = "dev-chassis",
                 hdop: float | None = None, hostile_after: float = 0.0, push_mps: float = 0.0,
                 push_after: float = 0.0) -> None:
        self.track = build_track(track)
        self.smap = TrackMap(self.track)
        self.lane = lane
        params = vehicle(vehicle_name)
        self.ref_ahead = -params.rear_axle_x
        start = self.track.start_pose(lane, start_s)
        axle = (start.x - self.ref_ahead * np.cos(start.yaw), start.y - self.ref_ahead * np.sin(start.yaw))
        self.plant = KinematicBicyclePlant(wheelbase=params.wheelbase, pose=Pose(*axle, start.yaw))
        self.channel = f"ld3-bench-{uuid.uuid4().hex[:10]}"
        self.bus = BusConfig("virtual", self.channel).open()
        self.ecu = EcuEmulator(self.bus, self.plant, EcuLimits(), ClockMode.REALTIME, profile=load_profile(profile),
                               wheels=WheelGeometry.of(params))
        self.ecu.start()
        self.hdop, self.hostile_after = hdop, hostile_after
        self.push_mps, self.push_after = push_mps, push_after
        self.max_off = 0.0
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._feed, daemon=True)
        self._thread.start()

    def _pose(self) -> Pose:
        p = self.plant.read().true_pose
        return Pose(p.x + self.ref_ahead * np.cos(p.yaw), p.y + self.ref_ahead * np.sin(p.yaw), p.yaw)

    def _feed(self) -> None:
        t0 = time.monotonic()
        moved: float | None = None
        while not self._stop.is_set():
            pose = self._pose()
            try:
                self.max_off = max(self.max_off, abs(self.smap.lane_dev(pose, self.lane)))
            except OffMapError:
                self.max_off = float("inf")
            if moved is None and abs(self.plant.read().speed) > 0.5:
                moved = time.monotonic()
            push = 0.0 if moved is None else max(time.monotonic() - moved - self.push_after, 0.0) * self.push_mps
            x, y = pose.x - push * np.sin(pose.yaw), pose.y + push * np.cos(pose.yaw)
            hostile = self.hdop is not None and time.monotonic() - t0 >= self.hostile_after
            os.write(self.master, gga(x, y, self.hdop if hostile else 0.05 / UERE_M[RTK]))
            self._stop.wait(0.1)

    def off_lane_m(self) -> float:
        return self.max_off

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.ecu.stop()
        self.bus.shutdown()
        os.close(self.master)
        os.close(self.slave)


def lane_video(path: Path, seconds: float, track: str = "parking-lot", vehicle_name: str = "dev-chassis") -> None:
    """An MJPG video at 20 fps of what `vehicle_name`'s camera sees from the centre of a straight lane of `track`'s
    lane-0 width: grey road, white lines, sky above the horizon."""
    import cv2

    rig = CameraRig(vehicle(vehicle_name).camera)
    half = build_track(track).lanes[0].width / 2
    image = np.full((rig.height, rig.width, 3), 85, np.uint8)
    image[: rig.height // 3] = (200, 170, 140)
    ahead = np.linspace(2.0, 40.0, 200)
    for side in (-half, half):
        uv = rig.ground_to_pixel(np.column_stack((ahead, np.full_like(ahead, side))))
        uv = uv[np.isfinite(uv).all(axis=1)]
        for (u0, v0), (u1, v1) in itertools.pairwise(uv):
            width = max(1, round(12 * (v0 - rig.height / 3) / rig.height))
            cv2.line(image, (int(u0), int(v0)), (int(u1), int(v1)), (235, 235, 235), width)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 20.0, (rig.width, rig.height))
    for _ in range(round(seconds * 20)):
        writer.write(image)
    writer.release()
