"""The loop on a real vehicle (`ld3 vehicle`): the world is real. GNSS comes from an NMEA stream, frames from a
camera (rectified by its calibration file), speed, steering, acceleration and yaw rate from the chassis reports
over any python-can interface (realtime clock, hardware rules); the map is a track preset placed on the Earth
at `origin`. The run starts on the first GNSS fix, in the map lane that fix lies in, heading along it.

It ends at `duration` (braking to standstill in lane before control is handed back), or on a fault: a chassis
or link fault, a stalled GNSS stream or camera, or the operator's SIGINT/SIGTERM (`interrupted`); the car then
brakes in lane and the run ends as chassis_fault. It writes trajectory.csv (poses are the MSF's: there is no
true pose on a vehicle), summary.json and the CAN log.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import numpy as np

from hil.bridge import CanChassisBridge
from hil.bus_config import BusConfig
from hil.camera_calibration import CameraCalibration, Rectifier
from hil.camera_reader import CameraReader, OpenCvSource
from hil.geodetic import LocalTangentPlane
from hil.interruption import interruptible
from hil.link_errors import LINK_ERRORS
from hil.nmea_gnss import NmeaGnssReader, open_nmea
from hil.odometry import KinematicOdometry, OdometryGeometry
from hil.profile import load_profile
from hil.recorder import FrameRecorder
from hil.secoc_key import link_key
from hil.timing import ClockMode
from hil.vehicle_localization import MeasuredLocalization
from testbed.chassis import ChassisCommand, ChassisFault, ChassisPort, ChassisState
from testbed.control.lateral import LqrLateralController
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES
from testbed.errors import UserError
from testbed.eval.outputs import provenance, write_trajectory
from testbed.eval.summary import VehicleSummary
from testbed.lane_detection import CameraFrame
from testbed.loop import ControlLoop, DrivingPorts, PerceptionPorts, SensorPorts, TickRecord
from testbed.perception.registry import DETECTORS, make_detector
from testbed.perception.tracker import LaneTracker
from testbed.presets import build_track, vehicle
from testbed.registry import Capability
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig

STANDSTILL_MPS = 0.05
CONTROL_HZ = 100.0


@dataclass(frozen=True)
class VehicleConfig:
    """What `ld3 vehicle` runs: map and its origin, sensors (`nmea:PATH`, `v4l2:/dev/videoN` or `video:PATH`,
    a calibration file), the components (the detector's weights file, if not its default), the vehicle's
    parameters, target speed (m/s) and duration (s)."""

    map: str
    origin: LocalTangentPlane
    gnss: str
    camera: str | None = None
    calibration: Path | None = None
    detector: str = "neural"
    detector_weights: str | None = None
    defense: str = "ld3"
    vehicle: str = "dev-chassis"
    speed: float = 2.0
    duration: float = 60.0
    lane: int | None = None
    profile: str = "ld3-dev"
    first_fix_s: float = 10.0

    def __post_init__(self) -> None:
        for key in ("speed", "duration", "first_fix_s"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise UserError(f"--{key.replace('_', '-')} must be a number > 0, got {value!r}")
        if self.lane is not None and self.lane < 0:
            raise UserError(f"--lane must be >= 0, got {self.lane}")


class ReportedChassis(ChassisPort):
    """The bridge as the loop sees it on a vehicle: what the chassis reports, no pose (its odometry is no truth)."""

    def __init__(self, bridge: CanChassisBridge) -> None:
        self.bridge = bridge

    def read(self) -> ChassisState:
        state = self.bridge.read()
        return ChassisState(state.t, state.speed, state.steer, state.accel, None, state.yaw_rate, state.mode,
                            state.faults)

    def send(self, cmd: ChassisCommand) -> None:
        self.bridge.send(cmd)

    def advance(self, dt: float) -> None:
        self.bridge.advance(dt)

    def latched_faults(self) -> tuple[ChassisFault, ...]:
        return self.bridge.latched_faults()


def _check_components(config: VehicleConfig) -> None:
    detector = DETECTORS.get(config.detector)
    reads_camera = Capability.CAMERA_IMAGE in detector.provides
    if config.detector != "none" and not reads_camera:
        cameras = [n for n in DETECTORS.names() if Capability.CAMERA_IMAGE in DETECTORS.get(n).provides]
        raise UserError(f"detector {config.detector} needs the simulator's true pose; on a vehicle use a camera "
                        f"detector ({', '.join(cameras)})")
    if reads_camera and config.camera is None:
        raise UserError(f"detector {config.detector} reads a camera: give --camera v4l2:/dev/videoN or video:PATH")
    if Capability.LANE_DETECTOR in DEFENSES.get(config.defense).needs and config.detector == "none":
        raise UserError(f"defense {config.defense} needs a lane detector: give --detector and --camera")
    if not config.gnss.startswith("nmea:"):
        raise UserError(f"--gnss takes nmea:PATH (a serial device, pty or file), got {config.gnss!r}")


class VehicleRun:
    """One `ld3 vehicle` run: opens the link and the sensors, waits for the first fix, drives, writes."""

    def __init__(self, config: VehicleConfig, bus: BusConfig, out_dir: Path) -> None:
        _check_components(config)
        self.config = config
        self.out_dir = out_dir
        self.track = build_track(config.map)
        self.smap = TrackMap(self.track)
        self.params = vehicle(config.vehicle)
        self.profile = load_profile(config.profile)
        key = link_key(self.profile, bus.interface, bus.kwargs().get("channel"))
        calibration = CameraCalibration.load(config.calibration) if config.calibration else None
        self.rig = CameraRig(calibration.rig_params(self.params.camera) if calibration else self.params.camera)
        self.bus = bus.open()
        self.interface = bus.interface
        self.readers: list[Any] = []
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
            self.recorder = FrameRecorder(out_dir / "can.asc")
            geometry = OdometryGeometry(wheelbase=self.params.wheelbase, ref_ahead=-self.params.rear_axle_x)
            self.bridge = CanChassisBridge(self.bus, clock=ClockMode.REALTIME, reply_timeout=5.0,
                                           profile=self.profile, odometry=KinematicOdometry(geometry=geometry), key=key)
            self.bridge.add_listener(self.recorder)
            self.gnss = NmeaGnssReader(open_nmea(config.gnss.removeprefix("nmea:")), config.origin, self.bridge.time)
            self.readers.append(self.gnss)
            self.camera: CameraReader | None = None
            if config.camera is not None:
                rectify = Rectifier(calibration, self.rig) if calibration else None
                self.camera = CameraReader(OpenCvSource(config.camera), self.bridge.time, rectify)
                self.readers.append(self.camera)
        except BaseException:
            self.close()
            raise

    def _start_pose(self) -> tuple[Pose, int]:
        deadline = time.monotonic() + self.config.first_fix_s
        while time.monotonic() < deadline:
            fixes = self.gnss.take(wait_s=0.2)
            if fixes:
                x, y = (float(v) for v in fixes[-1].xy)
                try:
                    coord = self.smap.project(Pose(x, y, 0.0), self.config.lane)
                    _, heading = self.smap.lane_point(Pose(x, y, 0.0), coord.lane)
                except OffMapError as exc:
                    raise UserError(f"the first GNSS fix is off the map {self.config.map}: {exc}; check --origin") \
                        from None
                return Pose(x, y, heading), coord.lane
        raise UserError(f"no GNSS fix from {self.config.gnss} within {self.config.first_fix_s:.0f} s "
                        f"({self.gnss.counts})")

    def _capture(self, t: float, pose: Pose | None) -> CameraFrame:
        frame = self.camera.capture(t, pose)
        if frame.image is None and (why := self.camera.stalled(t)) is not None:
            self.bridge.sensor_fault("camera_stalled", why)
        return frame

    def run(self) -> dict[str, Any]:
        """Drive until the duration or a fault; write the outputs and return the summary."""
        config = self.config
        start, lane = self._start_pose()
        self.bridge.odometry = KinematicOdometry(start, self.bridge.odometry.geometry)
        defense_config = DefenseConfig.from_dict({})
        defense = DEFENSES.get(config.defense).factory(defense_config,
                                                       BicycleCoefficients(wheelbase=self.params.wheelbase))
        params = {"weights": config.detector_weights} if config.detector_weights else {}
        detector = make_detector(config.detector, track=self.track, rig=self.rig, rng=np.random.default_rng(0),
                                 params=params)
        localization = MeasuredLocalization(self.gnss, start, self.bridge.sensor_fault)
        dt = 1.0 / CONTROL_HZ
        loop = ControlLoop(
            ReportedChassis(self.bridge),
            SensorPorts(localization, self._capture if self.camera is not None else None),
            PerceptionPorts(detector, defense_config.existence_threshold, None,
                            LaneTracker() if detector is not None else None),
            defense,
            DrivingPorts(self.smap, lane, LanePlanner(self.smap, lane, config.speed),
                         LqrLateralController.from_vehicle(self.params, dt),
                         SpeedController(max_accel=self.params.max_accel, max_decel=self.params.max_decel)),
        )
        rows: list[TickRecord] = []
        still_since: float | None = None
        wall0 = time.monotonic()
        with interruptible(self.bridge.interrupt):
            self.bridge.engage(timeout=5.0)
            with contextlib.suppress(KeyboardInterrupt):  # a second signal: stop driving the loop, close brakes
                while len(rows) < round(config.duration * CONTROL_HZ):
                    rec = loop.tick()
                    rows.append(rec)
                    stopping = loop.stopping or self.bridge.latched_faults()
                    still_since = (still_since if still_since is not None else rec.t) \
                        if stopping and abs(rec.speed) < STANDSTILL_MPS else None
                    if still_since is not None and rec.t - still_since >= 0.5:
                        break
        wall = time.monotonic() - wall0
        summary = self._summary(rows, defense, lane, still_since, wall)
        write_trajectory(self.out_dir / "trajectory.csv", rows)
        summary.write(self.out_dir / "summary.json")
        return summary.as_dict()

    def _summary(self, rows: list[TickRecord], defense, lane: int, stop_t: float | None,
                 wall: float) -> VehicleSummary:
        config, status = self.config, defense.status()
        faults = self.bridge.latched_faults()
        msf = np.array([np.nan if r.msf_dev is None else r.msf_dev for r in rows])
        run_time = rows[-1].t - rows[0].t + 1.0 / CONTROL_HZ if rows else 0.0
        consequence = "chassis_fault" if faults else "stop_in_lane" if stop_t is not None else "reach_destination"
        return VehicleSummary(**{
            **provenance(), "resolved_scenario": {"vehicle_run": {k: str(v) for k, v in vars(config).items()}},
            "scenario": "vehicle", "seed": None, "track": config.map, "vehicle": config.vehicle, "attack": None,
            "threat_model": "none",
            "defense": defense.name, "detector": config.detector,
            "localization": "msf: chassis reports + NMEA GNSS", "condition": "real", "sim_time_s": run_time,
            "wall_time_s": wall, "real_time_factor": run_time / wall if wall > 0 else None,
            "lane": lane, "lane_width_m": self.track.lanes[lane].width, "lane_straddle_dev_m": None,
            "max_abs_dev_m": None, "final_dev_m": None,
            "max_abs_msf_dev_m": float(np.nanmax(np.abs(msf))) if np.isfinite(msf).any() else None,
            "consequence": consequence,
            "faults": [{"kind": f.kind, "source": "chassis", "time": f.t, "detail": f.detail} for f in faults],
            "detected": bool(status.detected), "detection_time_s": status.detection_time, "detection_dev_m": None,
            "ar_max_dev_m": None, "ar_stop_dev_m": None, "stop_time_s": stop_t,
            "interface": self.interface, "profile": self.profile.name, "can_log": str(self.out_dir / "can.asc"),
            "can_frames_tx": self.bridge.frames_tx, "can_frames_rx": self.bridge.frames_rx,
            "nmea_fixes": self.gnss.counts.fixes, "nmea_bad": self.gnss.counts.bad,
            "nmea_no_fix": self.gnss.counts.no_fix, "camera_frames": self.camera.frames if self.camera else 0,
        })

    def close(self) -> None:
        """Brake to standstill and hand back (best effort), then stop the readers, the bridge and the bus."""
        bridge = getattr(self, "bridge", None)
        if bridge is not None:
            with contextlib.suppress(*LINK_ERRORS):  # must not mask the run's own outcome
                bridge.stop_and_release(timeout=10.0)
            bridge.close()
        for reader in self.readers:
            reader.close()
        with contextlib.suppress(can.CanError, OSError):  # a dead device cannot be closed cleanly
            self.bus.shutdown()
        if getattr(self, "recorder", None) is not None:
            self.recorder.stop()
