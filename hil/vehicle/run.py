"""The loop on a real vehicle (`ld3 vehicle`): the world is real. GNSS comes from an NMEA stream, frames from a
camera (rectified by its calibration file), speed, steering, acceleration and yaw rate from the chassis reports
over any python-can interface (realtime clock, hardware rules); the map is a track preset placed on the Earth
at `origin`. The run starts on the first GNSS fix, in the map lane that fix lies in, heading along it.

The loop is the one `testbed.assembly` builds for every run, at the `[rates]`, `[control]` and `[defense]` of
the settings; the yaw rate is the chassis's where the profile maps one, else derived (`hil.link.yaw_rate`). It ends
at `duration` of chassis time (braking to standstill in lane before control is handed back), or on a fault: a
chassis or link fault, a stalled GNSS stream or camera, a localization that keeps refusing its fixes or loses
its pose, or the operator's SIGINT/SIGTERM (`interrupted`); the car then brakes in lane and the run ends as
chassis_fault. It writes trajectory.csv (poses are the MSF's: there is no true pose on a vehicle), summary.json
(the consequence judged on the estimated pose, and named so), the CAN log, and with `record` run.mcap (what
LD3's detection read at each frame, for `ld3 replay`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from hil.link.bridge import BridgeError, CanChassisBridge
from hil.link.bus_config import BusConfig
from hil.link.errors import LINK_ERRORS
from hil.link.interruption import interruptible
from hil.link.odometry import KinematicOdometry, OdometryGeometry
from hil.link.profile import load_profile
from hil.link.recorder import RUN_LOG, FrameRecorder
from hil.link.scheduling import MAX_PRIORITY, RT_PRIORITY, normal_scheduling, realtime_scheduling
from hil.link.secoc_key import link_key
from hil.link.timing import ClockMode
from hil.link.yaw_rate import YawRateChassis
from hil.vehicle.camera_calibration import CameraCalibration
from hil.vehicle.camera_detect import source_fitter
from hil.vehicle.camera_reader import CameraReader, OpenCvSource
from hil.vehicle.geodetic import LocalTangentPlane
from hil.vehicle.localization import MeasuredLocalization
from hil.vehicle.nmea_gnss import NmeaGnssReader, open_nmea
from testbed.assembly import LanePorts, LoopRun, LoopSettings, assemble
from testbed.chassis import ChassisCommand, ChassisFault, ChassisPort, ChassisState
from testbed.control.config import ControlConfig
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.registry import DEFENSES, defense_settings, resolved_table
from testbed.errors import UserError
from testbed.eval.run.consequence import Consequence
from testbed.eval.run.outputs import provenance, write_trajectory
from testbed.eval.run.summary import VehicleSummary
from testbed.extras import missing_extra, require_modules
from testbed.lane_detection import CameraFrame, LaneDetection
from testbed.lane_tracker import LaneTracker
from testbed.loop import SensorPorts
from testbed.perception.detectors.registry import DETECTORS, make_detector
from testbed.presets import build_track, vehicle
from testbed.rates import Rates
from testbed.registry import Capability
from tracks.map_api import OffMapError
from tracks.pose import Pose
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig
from vehicles.params import VehicleParams


@dataclass(frozen=True)
class VehicleConfig:
    """What `ld3 vehicle` runs: map and its origin, sensors (`nmea:PATH`, `v4l2:/dev/videoN` or `video:PATH`,
    a calibration file), the components (the detector's weights file, if not its default), the vehicle's
    parameters, target speed (m/s), duration (s), the loop's rates, control and defense tables, and whether
    run.mcap is recorded."""

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
    rates: Rates = field(default_factory=Rates)
    control: ControlConfig = field(default_factory=ControlConfig)
    defense_params: dict[str, Any] = field(default_factory=dict)
    record: bool = False
    rt_priority: int = RT_PRIORITY

    def __post_init__(self) -> None:
        for key in ("speed", "duration", "first_fix_s"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise UserError(f"--{key.replace('_', '-')} must be a number > 0, got {value!r}")
        if self.lane is not None and self.lane < 0:
            raise UserError(f"--lane must be >= 0, got {self.lane}")
        if not 0 <= self.rt_priority < MAX_PRIORITY:
            raise UserError(f"--rt-priority must be 0 (none) to {MAX_PRIORITY - 1}, got {self.rt_priority}")

    def settings(self) -> LoopSettings:
        """The loop's settings: the speed, the duration and the `[rates]`, `[control]` and `[defense]` tables."""
        return LoopSettings(self.speed, self.duration, self.rates, self.control,
                            defense_settings(self.defense, self.defense_params)[0])


class ReportedChassis(ChassisPort):
    """The bridge as the loop sees it on a vehicle: what the chassis reports, its yaw rate from `yaw_rate_source`,
    no pose (the bridge's odometry is no truth)."""

    def __init__(self, bridge: CanChassisBridge, params: VehicleParams) -> None:
        self.bridge = bridge
        self.port = YawRateChassis(bridge, bridge.profile, params)

    def read(self) -> ChassisState:
        return dataclasses.replace(self.port.read(), true_pose=None)

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


def _check_place(config: VehicleConfig, track, max_speed: float) -> None:
    """The lane exists and is driven along the road; the speed is one the vehicle reaches."""
    if config.lane is not None:
        driven = len(track.lanes) - track.oncoming
        if config.lane >= len(track.lanes) or track.lanes[config.lane].oncoming:
            raise UserError(f"--lane {config.lane}: {config.map} has lanes 0..{driven - 1} along the road")
    if config.speed > max_speed:
        raise UserError(f"--speed {config.speed:g} m/s is beyond what {config.vehicle} can reach ({max_speed:g} m/s)")


class VehicleRun:
    """One `ld3 vehicle` run: opens the link and the sensors, waits for the first fix, drives, writes."""

    def __init__(self, config: VehicleConfig, bus: BusConfig, out_dir: Path) -> None:
        _check_components(config)
        self.config = config
        self.out_dir = out_dir
        self.track = build_track(config.map)
        self.smap = TrackMap(self.track)
        self.params = vehicle(config.vehicle)
        self.settings = config.settings()
        _check_place(config, self.track, self.params.max_speed)
        self.profile = load_profile(config.profile)
        key = link_key(self.profile, bus.interface, bus.kwargs().get("channel"))
        calibration = CameraCalibration.load(config.calibration) if config.calibration else None
        self.rig = CameraRig(calibration.rig_params(self.params.camera) if calibration else self.params.camera)
        params = {"weights": config.detector_weights} if config.detector_weights else {}
        try:
            self.detector = make_detector(config.detector, track=self.track, rig=self.rig,
                                          rng=np.random.default_rng(0), params=params)
        except ModuleNotFoundError as exc:
            raise missing_extra(exc, f"detector {config.detector}") from None
        self.recording = None
        if config.record:
            require_modules(("mcap",), "record", "--record")
            try:
                from testbed.eval.run.recording import Recording
            except ModuleNotFoundError as exc:
                raise missing_extra(exc, "--record") from None
            self.recording = Recording(self.rig)
        # from here, every thread the run starts (bus, receive, readers, pacer) inherits the realtime scheduling
        self.scheduling = realtime_scheduling(config.rt_priority)
        try:
            self.bus = bus.open()
        except BaseException:
            normal_scheduling()
            raise
        self.interface = bus.interface
        self.readers: list[Any] = []
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
            self.recorder = FrameRecorder(out_dir / RUN_LOG)
            geometry = OdometryGeometry(wheelbase=self.params.wheelbase, ref_ahead=-self.params.rear_axle_x)
            self.bridge = CanChassisBridge(self.bus, clock=ClockMode.REALTIME, reply_timeout=5.0,
                                           profile=self.profile, odometry=KinematicOdometry(geometry=geometry), key=key,
                                           pacer_priority=config.rt_priority + 1 if config.rt_priority else None)
            self.bridge.add_listener(self.recorder)
            self.gnss = NmeaGnssReader(open_nmea(config.gnss.removeprefix("nmea:")), config.origin, self.bridge.time)
            self.readers.append(self.gnss)
            self.camera: CameraReader | None = None
            if config.camera is not None:
                source = OpenCvSource(config.camera)  # frames that do not fit the detector are refused here
                self.camera = CameraReader(source, self.bridge.time, source_fitter(source, calibration, self.rig))
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
                        f"({self.gnss.counts.describe()})")

    def _capture(self, t: float, pose: Pose | None) -> CameraFrame:
        frame = self.camera.capture(t, pose)
        if frame.image is None and (why := self.camera.stalled(t)) is not None:
            self.bridge.sensor_fault("camera_stalled", why)
        return frame

    def run(self) -> dict[str, Any]:
        """Drive until the duration or a fault; write the outputs and return the summary."""
        config, settings = self.config, self.settings
        start, lane = self._start_pose()
        self.bridge.odometry = KinematicOdometry(start, self.bridge.odometry.geometry)
        defense = DEFENSES.get(config.defense).factory(defense_settings(config.defense, config.defense_params)[1],
                                                       BicycleCoefficients(wheelbase=self.params.wheelbase))
        self.localization = MeasuredLocalization(self.gnss, start, self.bridge.sensor_fault)
        chassis = ReportedChassis(self.bridge, self.params)
        run = assemble(settings, chassis,
                       SensorPorts(self.localization, self._capture if self.camera is not None else None),
                       defense, LanePorts(self.smap, lane, self.params), detector=self.detector,
                       tracker=LaneTracker() if self.detector is not None else None,
                       on_frame=self._record_frame if self.recording is not None else None)
        self._loop = run.loop
        wall0 = time.monotonic()
        with interruptible(self.bridge.interrupt):
            self.bridge.engage(timeout=5.0)
            with contextlib.suppress(KeyboardInterrupt):  # a second signal: stop driving the loop, close brakes
                while not run.done:
                    run.step()
            with contextlib.suppress(*LINK_ERRORS, BridgeError, KeyboardInterrupt):  # close() tries again
                self.bridge.stop_and_release(timeout=10.0)  # before the outputs: no gap in the command cycles
        wall = time.monotonic() - wall0
        summary = self._summary(run, defense, lane, chassis.port.source, wall)
        write_trajectory(self.out_dir / "trajectory.csv", run.rows)
        summary.write(self.out_dir / "summary.json")
        if self.recording is not None:
            self.recording.write(self.out_dir / "run.mcap")
        return summary.as_dict()

    def _record_frame(self, frame: CameraFrame, ld: LaneDetection) -> None:
        """What LD3's detection read at this frame: the detection and the tick's localization estimate."""
        self.recording.add_ld3_input(ld, self._loop.last_estimate)

    def _defense_table(self) -> dict[str, Any]:
        """The `[defense]` table as summary.json records it."""
        return resolved_table(*defense_settings(self.config.defense, self.config.defense_params))

    def _summary(self, run: LoopRun, defense, lane: int, yaw_source: str, wall: float) -> VehicleSummary:
        config, status, rows = self.config, defense.status(), run.rows
        faults = self.bridge.latched_faults()
        msf = np.array([np.nan if r.msf_dev is None else r.msf_dev for r in rows])
        run_time = run.elapsed_s
        width = self.track.lanes[lane].width
        straddle = 0.5 * (width - self.params.width)
        worst = float(np.nanmax(np.abs(msf))) if np.isfinite(msf).any() else None
        final = float(msf[-1]) if len(msf) and np.isfinite(msf[-1]) else None
        consequence = (Consequence.CHASSIS_FAULT if faults else Consequence.OUT_OF_LANE
                       if worst is None or worst > straddle else Consequence.STOP_IN_LANE if run.stop_t is not None
                       else Consequence.REACH_DESTINATION)
        return VehicleSummary(**{
            **provenance(), "resolved_scenario": {"vehicle_run": {k: str(v) for k, v in vars(config).items()},
                                                 "rates": self.settings.rates.model_dump(),
                                                 "control": self.settings.control.model_dump(),
                                                 "defense_params": self._defense_table()},
            "scenario": "vehicle", "seed": None, "track": config.map, "vehicle": config.vehicle, "attack": None,
            "threat_model": "none",
            "defense": defense.name, "defense_params": self._defense_table(),
            "detector": config.detector, "localization": "msf: chassis reports + NMEA GNSS", "condition": "real",
            "sim_time_s": run_time,
            "wall_time_s": wall, "real_time_factor": run_time / wall if wall > 0 else None,
            "lane": lane, "lane_width_m": width, "lane_straddle_dev_m": straddle,
            "max_abs_dev_m": None, "final_dev_m": final,
            "max_abs_msf_dev_m": worst, "consequence": consequence, "ended_by": run.ended_by,
            "faults": [{"kind": f.kind, "source": "chassis", "time": f.t, "detail": f.detail} for f in faults],
            "detected": bool(status.detected), "detection_time_s": status.detection_time, "detection_dev_m": None,
            "alarm_check": status.alarm_check,
            "ar_max_dev_m": None, "ar_stop_dev_m": None, "stop_time_s": run.stop_t,
            "rates": self.settings.rates.model_dump(), "yaw_rate_source": yaw_source,
            "interface": self.interface, "loop_scheduling": self.scheduling,
            "command_pacer": self.bridge.pacer_scheduling, "profile": self.profile.name,
            "can_log": RUN_LOG,  # in the run folder, named relative to it
            "can_frames_tx": self.bridge.frames_tx, "can_frames_rx": self.bridge.frames_rx,
            "nmea_fixes": self.gnss.counts.fixes, "nmea_bad": self.gnss.counts.bad,
            "nmea_no_fix": self.gnss.counts.no_fix,
            "nmea_refused": dict(self.gnss.counts.refused), "gnss_fixes_refused": self.localization.fixes_refused,
            "camera_frames": self.camera.frames if self.camera else 0,
            "odometry_bias_rad_per_m": defense.odometry_bias(),
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
        normal_scheduling()
        if getattr(self, "recorder", None) is not None:
            self.recorder.stop()
