"""Runs one scenario in simulation end to end (`SimRun` steps what `run_build` builds) and writes the output
contract (DESIGN.md)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from testbed.attacks.base import Attack
from testbed.attacks.compose import threat_model_of
from testbed.attacks.threat import threat_label
from testbed.chassis import ChassisPort
from testbed.defense.base import Defense
from testbed.eval.birdseye import save_birdseye
from testbed.eval.consequence import ConsequenceMonitor, footprint_corners
from testbed.eval.fusion_plot import has_fusion, save_fusion_plot
from testbed.eval.outputs import provenance, write_trajectory
from testbed.eval.recording import ego_lane_lines
from testbed.eval.run_build import RunOptions, build_run
from testbed.eval.run_folder import run_folder
from testbed.eval.scenario import END_MARGIN_M, Scenario, ScenarioError
from testbed.eval.summary import HitVehicle, RunSummary
from testbed.eval.video import FrameSignals
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.loop import SensorPorts, TickRecord
from testbed.traffic.fleet import EgoOnRoad
from testbed.traffic.record import RECORD_HZ, TrafficLog, vehicle_hit
from testbed.world import PhysicsWorld
from tracks.map_api import OffMapError
from tracks.pose import Pose

COLLISION_REACH_M = 15.0
"""Traffic cars whose centres lie farther than this plus a car length (reference arc length) from the ego's get no
physics body this tick: neither can close that gap within one control tick."""
STOP_SPEED = 0.05


@dataclass
class RunResult:
    """A finished run: its summary (`record`, and as the plain dict campaigns read), one record per control tick,
    the believed (MSF) path, the stop time."""

    record: RunSummary
    rows: list[TickRecord] = field(default_factory=list)
    believed_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    stop_t: float | None = None
    summary: dict[str, Any] = field(init=False)

    def __post_init__(self) -> None:
        self.summary = self.record.as_dict()


class SimRun:
    """Steps one simulated run, built from the scenario by `build_run`, to its end and returns its typed result;
    the run's parts (`RunParts`: the loop, the world, the track, ...) read as its attributes."""

    def __init__(self, sc: Scenario, *, render: bool | None = None, video: bool = False, record: bool = False,
                 chassis: ChassisPort | None = None, world: PhysicsWorld | None = None, ground: str = "canvas",
                 defense: Defense | None = None, detector: LaneDetector | None = None,
                 attack: Attack | list[Attack] | None = None, tracking: bool | None = None,
                 sensor_ports: Callable[[SensorPorts], SensorPorts] | None = None) -> None:
        """The keyword options are those of `RunOptions`."""
        self._frames: list[tuple[CameraFrame, LaneDetection]] = []
        options = RunOptions(render, video, record, chassis, world, ground, defense, detector, attack, tracking,
                             sensor_ports)
        self.parts = build_run(sc, options, self._keep_frame)
        left = self.lane + 1
        self.monitor = ConsequenceMonitor(self.parts.lane_width, self.params.width, self.params.length,
                                          left < len(self.track.lanes) and self.track.lanes[left].oncoming)
        self._half_diagonal = 0.5 * math.hypot(self.params.length, self.params.width)
        self.n_ticks = round(sc.duration * self.loop.rates.control_hz)
        self.rows: list[TickRecord] = []
        self.believed: list[tuple[float, float]] = []
        self.stop_t: float | None = None
        self._still_since: float | None = None
        self.wall_time = 0.0
        self.ended_by: str | None = None
        self.traffic_log = TrafficLog()
        self.hit: HitVehicle | None = None
        self._record_every = max(1, round(self.loop.rates.control_hz / RECORD_HZ))
        self._traffic_reach = 0.0
        self._traffic_dt = 1.0 / self.loop.rates.control_hz
        if self.traffic is not None:
            self._traffic_reach = (max(COLLISION_REACH_M, self.streamer.ahead if self.streamer is not None else 0.0)
                                   + self.traffic.length)

    @property
    def done(self) -> bool:
        """True once the run is over (`ended_by` says why)."""
        return self.ended_by is not None

    def __getattr__(self, name: str) -> Any:
        if name == "parts":  # not built yet
            raise AttributeError(name)
        return getattr(self.parts, name)

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

    def _edge_beyond(self, pose: Pose) -> str | None:
        """Kind of road edge a whole side of the footprint is beyond (two corners off the paved surface)."""
        track = self.parts.track
        if track.surface_holds_disc(pose.x, pose.y, self._half_diagonal):
            return None
        corners = footprint_corners(pose.x, pose.y, pose.yaw, self.params.length, self.params.width)
        kinds = [track.edge_kind_at(x, y) for x, y in corners]
        off = [k for k in kinds if k is not None]
        return off[0] if len(off) >= 2 else None

    def step(self) -> TickRecord:
        """One control tick, then the traffic's; sets `done` once the run is over: a consequence (curb, barrier,
        traffic car, off road, out of lane), standstill after a stop, the end of the road, or the scenario's
        duration."""
        if self.done:
            raise RuntimeError("the run is over; build a new SimRun to run again")
        wall0 = time.perf_counter()
        parts, loop = self.parts, self.parts.loop
        rec = loop.tick()
        self.rows.append(rec)
        est_pose = loop.last_estimate.pose
        self.believed.append((est_pose.x, est_pose.y))
        if parts.video is not None or parts.recording is not None:
            self._record_tick(rec)
        state = loop.last_state
        pose = state.true_pose
        world = parts.world
        contacts = world.contact_kinds() if world is not None else set()
        if "vehicle" in contacts and self.hit is None:
            self.hit = vehicle_hit(parts.traffic, world.traffic_touching()[0], rec.t, state.speed, pose.yaw)
        edge = self._edge_beyond(pose)
        if parts.traffic is not None:
            self._advance_traffic(rec, pose)
        if self.monitor.observe(rec.phys_dev, contacts, edge is not None, edge == "drop_off"):
            self.ended_by = "consequence"
        elif self._stopped(rec):
            self.ended_by = "standstill"
        elif parts.smap.project(pose, parts.lane).s > parts.track.length - END_MARGIN_M:
            self.ended_by = "road_end"
        elif len(self.rows) >= self.n_ticks:
            self.ended_by = "duration"
        self.wall_time += time.perf_counter() - wall0
        return rec

    def _advance_traffic(self, rec: TickRecord, pose: Pose) -> None:
        """Record the traffic cars as they stood during this tick (every `RECORD_HZ`-th; traffic.csv, run.mcap),
        move them to the next control instant behind the ego as it is now (off the map, it leads no car), and
        place the bodies (physics, camera) of those within reach of the ego's collision bodies or camera."""
        parts, fleet = self.parts, self.parts.traffic
        if (len(self.rows) - 1) % self._record_every == 0:
            every = fleet.poses()
            self.traffic_log.add(rec.t, fleet, every)
            if parts.recording is not None:
                parts.recording.add_traffic(rec.t, every)
        try:
            c = parts.smap.project(pose, parts.lane)
            ego = EgoOnRoad(c.s, c.l + parts.track.lanes[parts.lane].offset_at(c.s), rec.speed)
        except OffMapError:
            ego = None
        fleet.advance(self._traffic_dt, ego)
        near = fleet.cars if ego is None else fleet.near(ego.s, self._traffic_reach)
        poses = {car.id: p for car, p in zip(near, fleet.poses(near), strict=True)}
        parts.world.place_traffic(poses)
        if parts.streamer is not None:
            parts.streamer.place_traffic(poses)

    def _stopped(self, rec: TickRecord) -> bool:
        """True once the car has stood still for 0.5 s after a stop (response, planned stop or chassis fault)."""
        if not ((self.parts.loop.stopping or self.parts.chassis.latched_faults()) and abs(rec.speed) < STOP_SPEED):
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

    def _summary(self) -> RunSummary:
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
        return RunSummary(**{
            **provenance(), "resolved_scenario": {**sc.model_dump(), "defense_params": defense_params,
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
            "final_dev_m": final_dev, "consequence": consequence, "ended_by": self.ended_by,
            "faults": [{"kind": f.kind, "source": "chassis", "time": f.t, "detail": f.detail} for f in faults]
            + [{"kind": f.kind, "source": "defense", "time": f.time, "detail": f.detail, "last_time": f.last_time,
                "count": f.count} for f in self.defense.fault_records()],
            "detected": bool(status.detected), "detection_time_s": det_t,
            "detection_dev_m": float(np.nanmax(np.abs(before))) if det_t is not None and len(before) else None,
            "ar_max_dev_m": float(np.nanmax(np.abs(during))) if len(during) else None,
            "ar_stop_dev_m": final_dev if stop_t is not None else None,
            "stop_time_s": stop_t,
            "attack_state": self.attack.state() if self.attack is not None else None,
            "traffic_vehicles": len(self.traffic.cars) if self.traffic is not None else None,
            "hit_vehicle": self.hit,
        })

    def write_outputs(self, out_dir: Path, result: RunResult, title_suffix: str = "") -> None:
        """summary.json, trajectory.csv, traffic.csv (with traffic), birdseye.png (and camera.mp4, run.mcap when
        recorded) of a finished run."""
        sc = self.sc
        write_trajectory(out_dir / "trajectory.csv", result.rows)
        if self.traffic is not None:
            self.traffic_log.write(out_dir / "traffic.csv")
        result.record.write(out_dir / "summary.json")
        save_birdseye(out_dir / "birdseye.png", self.track, result.rows, lane_width=self.lane_width,
                      straddle_dev=self.monitor.straddle_dev, believed_xy=result.believed_xy,
                      detection_t=result.summary["detection_time_s"], stop_t=result.stop_t,
                      title=f"{sc.name} · {sc.track} · defense {sc.defense} · {result.summary['consequence']}"
                            + title_suffix,
                      attack_t=self.attack.start_time if self.attack is not None else None,
                      threshold=self.defense.alarm_threshold,
                      traffic=self.traffic_log.paths() if self.traffic is not None else None,
                      traffic_size=(self.traffic.length, self.traffic.width) if self.traffic is not None else (0, 0))
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
                 progress: bool = False, render: bool | None = None, tracking: bool | None = None,
                 force: bool = False) -> RunResult:
    """Run `sc`; when `out_dir` is given write summary.json, trajectory.csv, birdseye.png (and camera.mp4,
    run.mcap) there, all or nothing (`run_folder`; `force` replaces a finished run)."""
    if out_dir is None:
        return run_into(sc, None, video=video, record=record, progress=progress, render=render, tracking=tracking)
    with run_folder(out_dir, force) as tmp:
        return run_into(sc, tmp, video=video, record=record, progress=progress, render=render, tracking=tracking)


def run_into(sc: Scenario, out_dir: Path | None, *, video: bool = False, record: bool = False,
             progress: bool = False, render: bool | None = None, tracking: bool | None = None) -> RunResult:
    """Run `sc` and write its outputs into `out_dir`, a folder the caller made and owns (a campaign's
    temporary run folder), or nowhere."""
    sim = SimRun(sc, render=render, video=video, record=record, tracking=tracking)
    try:
        result = sim.run(progress=progress)
        if out_dir is not None:
            sim.write_outputs(out_dir, result)
        return result
    finally:
        sim.close()
