"""Runs one scenario in simulation end to end and writes the output contract (DESIGN.md).

The run's random streams are spawned from the scenario seed in a fixed order (camera noise,
localization, attack, detector), so the same scenario and seed give byte-identical trajectories.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from testbed.attacks.base import Attack, WhiteBox
from testbed.attacks.compose import AttackChain, threat_model_of
from testbed.attacks.spec import build_attack
from testbed.attacks.threat import threat_label
from testbed.camera import FrontCamera
from testbed.chassis import ChassisPort
from testbed.conditions import get_condition
from testbed.control.lateral import LqrLateralController
from testbed.control.longitudinal import SpeedController
from testbed.control.planner import LanePlanner
from testbed.defense.base import Defense
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES
from testbed.direct_chassis import DirectChassis
from testbed.eval.birdseye import save_birdseye
from testbed.eval.consequence import ConsequenceMonitor, footprint_corners
from testbed.eval.fusion_plot import has_fusion, save_fusion_plot
from testbed.eval.outputs import provenance, write_summary, write_trajectory
from testbed.eval.recording import Recording, ego_lane_lines
from testbed.eval.scenario import Scenario, ScenarioError, check_needs
from testbed.eval.video import FrameSignals, VideoWriter
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.localization.registry import LOCALIZATIONS
from testbed.localization.stack import LocalizationConfig
from testbed.loop import ControlLoop, DrivingPorts, LoopRates, PerceptionPorts, SensorPorts, TickRecord
from testbed.perception.registry import DETECTORS, make_detector
from testbed.perception.tracker import LaneTracker
from testbed.presets import build_track, vehicle
from testbed.registry import Capability
from testbed.world import PHYSICS_HZ, PhysicsWorld, TileStreamer
from tracks.pose import Pose
from tracks.semantic_map import TrackMap
from vehicles.camera_rig import CameraRig

STOP_SPEED = 0.05
END_MARGIN_M = 30.0


@dataclass
class RunResult:
    """A finished run: its summary, one record per control tick, the believed (MSF) path, the stop time."""

    summary: dict[str, Any]
    rows: list[TickRecord] = field(default_factory=list)
    believed_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    stop_t: float | None = None


def physics_world_for(sc: Scenario, track, params, start: Pose) -> PhysicsWorld:
    """The physics world a scenario runs in (the CAN chassis emulator builds the same one as its plant)."""
    return PhysicsWorld(track, params, start, physics_hz=sc.rates.get("physics_hz", PHYSICS_HZ))


class SimRun:
    """Everything one simulated scenario needs, built from the scenario; `run()` drives it to the end."""

    def __init__(self, sc: Scenario, *, render: bool | None = None, video: bool = False, record: bool = False,
                 chassis: ChassisPort | None = None, world: PhysicsWorld | None = None, ground: str = "canvas",
                 defense: Defense | None = None, detector: LaneDetector | None = None,
                 attack: Attack | list[Attack] | None = None, tracking: bool | None = None,
                 sensor_ports: Callable[[SensorPorts], SensorPorts] | None = None) -> None:
        """`chassis` replaces the direct PyBullet port (the CAN bridge does this); `world`, when given with it,
        is the physics world behind that chassis, used for contacts. Without `chassis` the run builds both.
        `video` and `record` also write camera.mp4 and run.mcap. `ground` is how the camera draws the road
        surface (`TileStreamer`). `defense`, `detector` and `attack` replace the ones the scenario names (your
        own objects, or a passive detection recorder; a list of attacks is composed in order); the summary
        records their own names. `tracking` puts a
        `LaneTracker` after the detector (default: the scenario's `detector.tracking`, or for an injected
        detector, whether it reads the camera). `sensor_ports` wraps the sensor ports the run builds
        (sensor-level HIL passes them through real readers)."""
        self.sc = sc
        self.track = build_track(sc.track)
        self.params = vehicle(sc.vehicle)
        self.condition = get_condition(sc.condition)
        self.defense_config = DefenseConfig.from_dict(sc.defense_params)
        provided = check_needs(sc)
        if sc.speed > self.params.max_speed:
            raise ScenarioError(f"speed {sc.speed} m/s is beyond what {sc.vehicle} can reach "
                                f"({self.params.max_speed} m/s)")
        seeds = np.random.SeedSequence(sc.seed).spawn(4)
        rng_camera, rng_loc, rng_attack, rng_detector = (np.random.default_rng(s) for s in seeds)
        self.smap = TrackMap(self.track)
        self.lane = sc.lane if sc.lane is not None else self.track.ego_lane
        if not 0 <= self.lane < len(self.track.lanes):
            raise ScenarioError(f"lane {self.lane} does not exist on {sc.track} ({len(self.track.lanes)} lanes)")
        start = self.track.start_pose(self.lane, sc.start_s)
        self.start = start
        if chassis is None:
            world = physics_world_for(sc, self.track, self.params, start)
            chassis = DirectChassis(world, hold_s=sc.rates.get("command_hold_s", 0.0))
        self.world = world
        self.chassis = chassis
        rates = LoopRates(control_hz=sc.rates.get("control_hz", 100.0), camera_hz=sc.rates.get("camera_hz", 20.0))
        self.attack: Attack | None = AttackChain(attack) if isinstance(attack, list) else attack
        if attack is None:
            self.attack = build_attack(sc.attack, rng=rng_attack, defense=self.defense_config)
        for painter in self.condition.track_painters(sc.seed):
            self.track.add_painter(painter)
        if self.attack is not None:
            for painter in self.attack.painters():
                self.track.add_painter(painter)
        reads_camera = Capability.CAMERA_IMAGE in provided if detector is None else detector.reads_camera
        needs_camera = reads_camera if render is None else render
        self.rig = CameraRig(self.params.camera)
        self.streamer: TileStreamer | None = None
        self.camera: FrontCamera | None = None
        if needs_camera or video or record:
            self.streamer = TileStreamer(self.track, self.condition.lighting, ground=ground)
            self.camera = FrontCamera(self.streamer, self.rig, self.condition, rng_camera)
        self.video = VideoWriter(self.rig, fps=rates.camera_hz) if video else None
        self.recording = Recording(self.rig) if record else None
        self._frames: list[tuple[CameraFrame, LaneDetection]] = []
        self.localization = LOCALIZATIONS.get(sc.localization).factory(self._localization_config, rng_loc,
                                                                        self._lidar_quality, start)
        self.detector = detector if detector is not None else make_detector(
            sc.detector, track=self.track, rig=self.rig, rng=rng_detector, params=sc.detector_params)
        self.detector_name = sc.detector if detector is None else getattr(detector, "name", type(detector).__name__)
        self.detector_settings = (DETECTORS.get(sc.detector).settings(sc.detector_params, f"detector {sc.detector}")
                                  if detector is None else None)
        """The scenario's detector's `[detector]` parameters, defaults filled in (None for an injected detector)."""
        if tracking is None:
            tracking = (getattr(self.detector_settings, "tracking", False) if detector is None
                        else detector.reads_camera)
        if tracking and self.detector is None:
            raise ScenarioError("tracking needs a lane detector; name one, or turn tracking off")
        self.tracker = LaneTracker() if tracking else None
        if (self.defense_config.p_source == "reported" and self.detector is not None
                and not self.detector.reports_variance):
            raise ScenarioError(f"defense.p_source = 'reported' needs a lane detector that reports its c0 variance; "
                                f"{sc.detector!r} does not: use detector oracle, or defense.p_source = 'constant'")
        self.defense = defense if defense is not None else DEFENSES.get(sc.defense).factory(
            self.defense_config, BicycleCoefficients(wheelbase=self.params.wheelbase))
        dt = 1.0 / rates.control_hz
        sensors = SensorPorts(self.localization, self._capture if self.camera else None)
        self.loop = ControlLoop(
            self.chassis,
            sensor_ports(sensors) if sensor_ports is not None else sensors,
            PerceptionPorts(self.detector, self.defense_config.existence_threshold,
                            self._keep_frame if (video or record) else None, self.tracker),
            self.defense,
            DrivingPorts(self.smap, self.lane, LanePlanner(self.smap, self.lane, sc.speed),
                         LqrLateralController.from_vehicle(self.params, dt),
                         SpeedController(max_accel=self.params.max_accel, max_decel=self.params.max_decel),
                         planned_stop=(sc.stop_at, sc.stop_decel) if sc.stop_at is not None else None),
            attack=self.attack, rates=rates,
        )
        if self.attack is not None:
            self.attack.know(WhiteBox(self.smap, self.lane, self.defense_config, rates.camera_hz, rates.control_hz,
                                      self._lidar_quality))
        lane_width = self.smap.lane_width(start, self.lane)
        self.lane_width = lane_width
        self.monitor = ConsequenceMonitor(lane_width, self.params.width, self.params.length)
        self.n_ticks = round(sc.duration * rates.control_hz)
        self.rows: list[TickRecord] = []
        self.believed: list[tuple[float, float]] = []
        self.stop_t: float | None = None
        self._still_since: float | None = None
        self.wall_time = 0.0
        self.done = False

    def _localization_config(self) -> LocalizationConfig:
        """The scenario's localization table, with the MSF lever arm (rear axle to reference point) of the car."""
        table = dict(self.sc.rates.get("localization", {}))
        table["msf"] = {"lever": -self.params.rear_axle_x, **table.get("msf", {})}
        return LocalizationConfig.from_dict(table)

    def _keep_frame(self, frame: CameraFrame, ld: LaneDetection) -> None:
        """A camera frame and its detection, held until the tick's record exists (video and recording)."""
        self._frames.append((frame, ld))

    def _record_tick(self, rec: TickRecord) -> None:
        """Hand the tick and the frames that arrived on it to the video and the recording."""
        tau = self.defense.alarm_threshold
        for frame, ld in self._frames:
            if self.video is not None:
                self.video.add(frame, ld, FrameSignals.of(rec, tau))
            if self.recording is not None:
                self.recording.add_camera(frame.t, frame.image, ld)
                self.recording.add_ld3_input(ld, self.loop.last_estimate)
        self._frames.clear()
        if self.recording is not None:
            control = self.loop.last_control_pose if rec.mode == "ar" else None
            self.recording.add_tick(rec, self.loop.last_estimate.pose, control, tau)

    def _lidar_quality(self, x: float, y: float) -> float:
        """LiDAR feature richness at a world point (the track's profile along the road)."""
        s, _ = self.track.reference.project(x, y)
        return self.track.lidar_feature_quality(s)

    def _capture(self, t: float, pose: Pose):
        self.streamer.update(pose)
        return self.camera.capture(t, pose)

    def _edge_beyond(self, pose: Pose) -> str | None:
        """Kind of road edge a whole side of the footprint is beyond (two corners off the paved surface)."""
        if self.track.surface_holds_disc(pose.x, pose.y, 0.5 * math.hypot(self.params.length, self.params.width)):
            return None
        corners = footprint_corners(pose.x, pose.y, pose.yaw, self.params.length, self.params.width)
        kinds = [self.track.edge_kind_at(x, y) for x, y in corners]
        off = [k for k in kinds if k is not None]
        return off[0] if len(off) >= 2 else None

    def step(self) -> TickRecord:
        """One control tick; sets `done` once the run is over: a consequence (curb, barrier, off road, out of
        lane), standstill after a stop, the end of the road, or the scenario's duration."""
        if self.done:
            raise RuntimeError("the run is over; build a new SimRun to run again")
        wall0 = time.perf_counter()
        rec = self.loop.tick()
        self.rows.append(rec)
        est_pose = self.loop.last_estimate.pose
        self.believed.append((est_pose.x, est_pose.y))
        if self.video is not None or self.recording is not None:
            self._record_tick(rec)
        pose = self.loop.last_state.true_pose
        contacts = self.world.contact_kinds() if self.world is not None else set()
        edge = self._edge_beyond(pose)
        self.done = (self.monitor.observe(rec.phys_dev, contacts, edge is not None, edge == "drop_off")
                     or self._stopped(rec) or self.smap.project(pose, self.lane).s > self.track.length - END_MARGIN_M
                     or len(self.rows) >= self.n_ticks)
        self.wall_time += time.perf_counter() - wall0
        return rec

    def _stopped(self, rec: TickRecord) -> bool:
        """True once the car has stood still for 0.5 s after a stop (response, planned stop or chassis fault)."""
        if not ((self.loop.stopping or self.chassis.latched_faults()) and abs(rec.speed) < STOP_SPEED):
            self._still_since = None
            return False
        self._still_since = rec.t if self._still_since is None else self._still_since
        if rec.t - self._still_since < 0.5:
            return False
        self.stop_t = self._still_since
        return True

    def run(self, progress: bool = False) -> RunResult:
        """Step to the end and return the result."""
        bar = tqdm(total=self.n_ticks, desc=f"{self.sc.name}", unit="tick", disable=not progress, leave=False)
        while not self.done:
            self.step()
            bar.update(1)
        bar.close()
        return self.result()

    def result(self) -> RunResult:
        """The summary and records of the ticks run so far (the whole run once `done`)."""
        return RunResult(self._summary(), list(self.rows), np.array(self.believed).reshape(-1, 2), self.stop_t)

    def _summary(self) -> dict[str, Any]:
        sc, rows, wall, stop_t = self.sc, self.rows, self.wall_time, self.stop_t
        status = self.defense.status()
        det_t = status.detection_time
        phys = np.array([np.nan if r.phys_dev is None else r.phys_dev for r in rows])
        t = np.array([r.t for r in rows])
        final_dev = float(phys[-1]) if len(phys) else math.nan
        before = phys[t <= det_t] if det_t is not None else phys
        during = phys[t >= det_t] if det_t is not None else np.array([])
        sim_time = float(t[-1] + 1.0 / self.loop.rates.control_hz) if len(t) else 0.0
        faults = self.chassis.latched_faults()
        consequence = ("chassis_fault" if faults else
                       self.monitor.final(stopped_by_response=stop_t is not None, final_dev=final_dev))
        defense_params = self.defense_config.model_dump()
        return {
            **provenance(), "resolved_scenario": {**dataclasses.asdict(sc), "defense_params": defense_params,
                                                 "detector_params": self.detector_settings.model_dump()
                                                 if self.detector_settings is not None else {}},
            "scenario": sc.name, "seed": sc.seed, "track": sc.track, "vehicle": sc.vehicle,
            "attack": self.attack.describe() if self.attack is not None else None,
            "threat_model": threat_label(threat_model_of(self.attack)),
            "defense": self.defense.name, "defense_params": defense_params,
            "condition": sc.condition, "detector": self.detector_name, "tracking": self.tracker is not None,
            "localization": sc.localization, "target_speed_mps": sc.speed,
            "sim_time_s": sim_time, "wall_time_s": wall, "real_time_factor": sim_time / wall if wall > 0 else None,
            "lane_width_m": self.lane_width, "lane_straddle_dev_m": self.monitor.straddle_dev,
            "max_abs_dev_m": float(np.nanmax(np.abs(phys))) if np.isfinite(phys).any() else None,
            "final_dev_m": final_dev, "consequence": consequence,
            "faults": [{"kind": f.kind, "source": "chassis", "time": f.t, "detail": f.detail} for f in faults]
            + [{"kind": f.kind, "source": "defense", "time": f.time, "detail": f.detail, "last_time": f.last_time,
                "count": f.count} for f in self.defense.fault_records()],
            "detected": bool(status.detected), "detection_time_s": det_t,
            "detection_dev_m": float(np.nanmax(np.abs(before))) if det_t is not None and len(before) else None,
            "ar_max_dev_m": float(np.nanmax(np.abs(during))) if len(during) else None,
            "ar_stop_dev_m": final_dev if stop_t is not None else None,
            "stop_time_s": stop_t,
            "attack_state": self.attack.state() if self.attack is not None else None,
        }

    def write_outputs(self, out_dir: Path, result: RunResult, title_suffix: str = "") -> None:
        """summary.json, trajectory.csv, birdseye.png (and camera.mp4 when recorded) of a finished run."""
        sc = self.sc
        write_trajectory(out_dir / "trajectory.csv", result.rows)
        write_summary(out_dir / "summary.json", result.summary)
        save_birdseye(out_dir / "birdseye.png", self.track, result.rows, lane_width=self.lane_width,
                      straddle_dev=self.monitor.straddle_dev, believed_xy=result.believed_xy,
                      detection_t=result.summary["detection_time_s"], stop_t=result.stop_t,
                      title=f"{sc.name} · {sc.track} · defense {sc.defense} · {result.summary['consequence']}"
                            + title_suffix,
                      attack_t=self.attack.start_time if self.attack is not None else None,
                      threshold=self.defense.alarm_threshold)
        if self.attack is not None and has_fusion(result.rows):
            save_fusion_plot(out_dir / "ar_fusion.png", result.rows, straddle_dev=self.monitor.straddle_dev,
                             title=f"{sc.name} · {sc.track} · {self.attack.name} · attack response")
        if self.video is not None:
            self.video.write(out_dir / "camera.mp4")
        if self.recording is not None:
            path = np.array([(r.x, r.y) for r in result.rows]).reshape(-1, 2)
            self.recording.set_lane_lines(ego_lane_lines(self.track.lanes[self.lane], path))
            self.recording.write(out_dir / "run.mcap")

    def close(self) -> None:
        if self.video is not None:
            self.video.close()
        if self.world is not None:
            self.world.close()
        if self.streamer is not None:
            self.streamer.close()


def prepare_out_dir(out_dir: Path) -> None:
    """Create the output directory and prove it writable, or raise a one-line ScenarioError."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise ScenarioError(f"cannot write to output directory {out_dir}: {exc.strerror}") from None


def run_scenario(sc: Scenario, out_dir: Path | None, *, video: bool = False, record: bool = False,
                 progress: bool = False, render: bool | None = None, tracking: bool | None = None) -> RunResult:
    """Run `sc`; when `out_dir` is given write summary.json, trajectory.csv, birdseye.png (and camera.mp4,
    run.mcap)."""
    if out_dir is not None:
        prepare_out_dir(out_dir)
    sim = SimRun(sc, render=render, video=video, record=record, tracking=tracking)
    try:
        result = sim.run(progress=progress)
        if out_dir is not None:
            sim.write_outputs(out_dir, result)
        return result
    finally:
        sim.close()
