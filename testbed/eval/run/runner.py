"""Runs one scenario in simulation end to end (`SimRun` steps what `run_build` builds) and writes the output
contract (docs/outputs.md)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from testbed.assembly import LoopRun
from testbed.attacks.base import Attack
from testbed.attacks.compose import threat_model_of
from testbed.attacks.threat import threat_label
from testbed.chassis import ChassisPort
from testbed.defense.base import Defense
from testbed.eval.run.build import RunOptions, build_run
from testbed.eval.run.consequence import Consequence, ConsequenceMonitor, footprint_corners
from testbed.eval.run.figures import BELIEVED, FigureInputs, fusion_title, save_run_figures, write_believed
from testbed.eval.run.folder import run_folder
from testbed.eval.run.outputs import provenance, write_trajectory
from testbed.eval.run.recording import ego_lane_lines
from testbed.eval.run.scenario import END_MARGIN_M, Scenario, ScenarioError
from testbed.eval.run.summary import RunSummary
from testbed.eval.run.video import FrameSignals
from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from testbed.loop import SensorPorts, TickRecord, safe_dev
from testbed.traffic.fleet import EgoOnRoad
from testbed.traffic.record import RECORD_HZ, HitVehicle, TrafficLog, vehicle_hit
from testbed.world import PhysicsWorld
from tracks.map_api import OffMapError
from tracks.pose import Pose

COLLISION_REACH_M = 15.0
"""Traffic cars whose centres lie farther than this plus a car length (reference arc length) from the ego's get no
physics body this tick: neither can close that gap within one control tick."""


@dataclass
class RunResult:
    """A finished run: its summary (`record`, and as the plain dict the Python API hands out), one record per tick,
    the believed (MSF) path, the stop time."""

    record: RunSummary
    rows: list[TickRecord] = field(default_factory=list)
    believed_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    stop_t: float | None = None
    summary: dict[str, Any] = field(init=False)

    def __post_init__(self) -> None:
        self.summary = self.record.as_dict()


def max_abs_dev(values: np.ndarray) -> float | None:
    """The largest |value| among the finite ones (a car off the map has no deviation), None when there is none."""
    finite = values[np.isfinite(values)]
    return float(np.max(np.abs(finite))) if len(finite) else None


class SimRun:
    """Steps one simulated run to its end and returns its typed result: `parts` is what `build_run` built from
    the scenario (the loop run, the world, the track, ...); this adds the simulator's hooks (contacts, traffic,
    video and recording) and end conditions (a consequence before standstill, the end of the road after it).

    The consequence, the end of the road and the summary's deviations are judged on the chassis's true pose, or
    with `plant_pose` on the pose it reads after each tick (as the contacts are): the car behind a chassis port
    whose pose is not that car's (the CAN bridge's odometry before an emulated plant)."""

    def __init__(self, sc: Scenario, *, render: bool | None = None, video: bool = False, record: bool = False,
                 chassis: ChassisPort | None = None, world: PhysicsWorld | None = None, ground: str = "canvas",
                 defense: Defense | None = None, detector: LaneDetector | None = None,
                 attack: Attack | list[Attack] | None = None, tracking: bool | None = None,
                 sensor_ports: Callable[[SensorPorts], SensorPorts] | None = None,
                 plant_pose: Callable[[], Pose | None] | None = None) -> None:
        """The keyword options are those of `RunOptions`, and `plant_pose` (None: not known at that tick)."""
        self.sc = sc
        self._frames: list[tuple[CameraFrame, LaneDetection]] = []
        options = RunOptions(render, video, record, chassis, world, ground, defense, detector, attack, tracking,
                             sensor_ports)
        self.parts = parts = build_run(sc, options, self._keep_frame)
        self.run_loop: LoopRun = parts.run
        self.loop = parts.run.loop
        params, track, lane = parts.params, parts.track, parts.lane
        left = lane + 1
        self.monitor = ConsequenceMonitor(parts.lane_width, params.width, params.length,
                                          left < len(track.lanes) and track.lanes[left].oncoming)
        self._half_diagonal = 0.5 * math.hypot(params.length, params.width)
        self.n_ticks = round(sc.duration * sc.rates.control_hz)
        self.believed: list[tuple[float, float]] = []
        self.wall_time = 0.0
        self.traffic_log = TrafficLog()
        self.hit: HitVehicle | None = None
        self._record_every = max(1, round(sc.rates.control_hz / RECORD_HZ))
        self._traffic_reach = 0.0
        self._traffic_dt = sc.rates.control_dt
        if parts.traffic is not None:
            self._traffic_reach = (max(COLLISION_REACH_M, parts.streamer.ahead if parts.streamer is not None else 0.0)
                                   + parts.traffic.length)
        self._contacts: set[str] = set()
        self._edge: str | None = None
        self._plant_pose = plant_pose
        self._plant: Pose | None = None
        self._plant_devs: list[float | None] = []
        self.run_loop.add_hook(self._observe)
        self.run_loop.add_end(self._consequence, before_standstill=True)
        self.run_loop.add_end(self._road_end)

    @property
    def rows(self) -> list[TickRecord]:
        return self.run_loop.rows

    @property
    def stop_t(self) -> float | None:
        return self.run_loop.stop_t

    @property
    def ended_by(self) -> str | None:
        return self.run_loop.ended_by

    @property
    def judged_devs(self) -> list[float | None]:
        """D per tick of the pose the run is judged on (None: off the map, no pose that tick, or a tick cut short
        by a second interruption before its hooks ran)."""
        if self._plant_pose is None:
            return [r.phys_dev for r in self.rows]
        return self._plant_devs + [None] * (len(self.rows) - len(self._plant_devs))

    def _judged_pose(self) -> Pose | None:
        """The pose the run is judged on as of the last tick: the plant's, else the chassis's true pose."""
        return self.loop.last_state.true_pose if self._plant_pose is None else self._plant

    @property
    def done(self) -> bool:
        """True once the run is over (`ended_by` says why)."""
        return self.run_loop.done

    def _keep_frame(self, frame: CameraFrame, ld: LaneDetection) -> None:
        """A camera frame and its detection, held until the tick's record exists (video and recording)."""
        self._frames.append((frame, ld))

    def _record_tick(self, rec: TickRecord) -> None:
        """Hand the tick and the frames that arrived on it to the video and the recording."""
        parts = self.parts
        tau = parts.defense.alarm_threshold
        for frame, ld in self._frames:
            if parts.video is not None:
                parts.video.add(frame, ld, FrameSignals.of(rec, tau))
            if parts.recording is not None:
                parts.recording.add_camera(frame.t, frame.image, ld)
                parts.recording.add_ld3_input(ld, self.loop.last_estimate)
        self._frames.clear()
        if parts.recording is not None:
            control = self.loop.last_control_pose if rec.mode == "ar" else None
            parts.recording.add_tick(rec, self.loop.last_estimate.pose, control, tau)

    def _edge_beyond(self, pose: Pose) -> str | None:
        """Kind of road edge a whole side of the footprint is beyond (two corners off the paved surface)."""
        track, params = self.parts.track, self.parts.params
        if track.surface_holds_disc(pose.x, pose.y, self._half_diagonal):
            return None
        corners = footprint_corners(pose.x, pose.y, pose.yaw, params.length, params.width)
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
        rec = self.run_loop.step()
        self.wall_time += time.perf_counter() - wall0
        return rec

    def _observe(self, rec: TickRecord) -> None:
        """The tick as the simulator sees it: the believed pose, video and recording, contacts and the road edge
        under the true footprint, then the traffic's step."""
        parts, loop = self.parts, self.loop
        est_pose = loop.last_estimate.pose
        self.believed.append((est_pose.x, est_pose.y))
        if parts.video is not None or parts.recording is not None:
            self._record_tick(rec)
        state = loop.last_state
        if self._plant_pose is not None:
            self._plant = self._plant_pose()
            self._plant_devs.append(safe_dev(parts.smap, self._plant, parts.lane) if self._plant is not None
                                    else None)
        judged = self._judged_pose()
        world = parts.world
        self._contacts = world.contact_kinds() if world is not None else set()
        if "vehicle" in self._contacts and self.hit is None:
            self.hit = vehicle_hit(parts.traffic, world.traffic_touching()[0], rec.t, state.speed, judged.yaw)
        self._edge = self._edge_beyond(judged) if judged is not None else None
        if parts.traffic is not None:
            self._advance_traffic(rec, state.true_pose)

    def _consequence(self, rec: TickRecord) -> str | None:
        dev = rec.phys_dev if self._plant_pose is None else self._plant_devs[-1]
        if self.monitor.observe(dev, self._contacts, self._edge is not None, self._edge == "drop_off"):
            return "consequence"
        return None

    def _road_end(self, rec: TickRecord) -> str | None:
        parts, pose = self.parts, self._judged_pose()
        if pose is None:
            return None
        try:
            s = parts.smap.project(pose, parts.lane).s
        except OffMapError:  # a car off the map is at no road's end; the consequence monitor judges where it went
            return None
        return "road_end" if s > parts.track.length - END_MARGIN_M else None

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
        status = self.parts.defense.status()
        det_t = status.detection_time
        phys = np.array([np.nan if d is None else d for d in self.judged_devs])
        t = np.array([r.t for r in rows])
        final_dev = float(phys[-1]) if len(phys) else math.nan
        before = phys[t <= det_t] if det_t is not None else phys
        during = phys[t >= det_t] if det_t is not None else np.array([])
        sim_time = float(t[-1] + self.loop.dt) if len(t) else 0.0
        faults = self.parts.chassis.latched_faults()
        consequence = (Consequence.CHASSIS_FAULT if faults else
                       self.monitor.final(stopped_by_response=stop_t is not None, final_dev=final_dev))
        defense_params = self.parts.defense_table
        return RunSummary(**{
            **provenance(), "resolved_scenario": {**sc.model_dump(), "defense_params": defense_params,
                                                 "detector_params": self.parts.detector_settings.model_dump()
                                                 if self.parts.detector_settings is not None else {}},
            "scenario": sc.name, "seed": sc.seed, "track": sc.track, "vehicle": sc.vehicle,
            "attack": self.parts.attack.describe() if self.parts.attack is not None else None,
            "threat_model": threat_label(threat_model_of(self.parts.attack)),
            "defense": self.parts.defense.name, "defense_params": defense_params,
            "condition": sc.condition, "detector": self.parts.detector_name, "tracking": self.parts.tracker is not None,
            "localization": sc.localization, "target_speed_mps": sc.speed,
            "sim_time_s": sim_time, "wall_time_s": wall, "real_time_factor": sim_time / wall if wall > 0 else None,
            "lane_width_m": self.parts.lane_width, "lane_straddle_dev_m": self.monitor.straddle_dev,
            "max_abs_dev_m": max_abs_dev(phys),
            "final_dev_m": final_dev, "consequence": consequence, "ended_by": self.ended_by,
            "faults": [{"kind": f.kind, "source": "chassis", "time": f.t, "detail": f.detail} for f in faults]
            + [{"kind": f.kind, "source": "defense", "time": f.time, "detail": f.detail, "last_time": f.last_time,
                "count": f.count} for f in self.parts.defense.fault_records()],
            "detected": bool(status.detected), "detection_time_s": det_t,
            "detection_dev_m": max_abs_dev(before) if det_t is not None else None, "alarm_check": status.alarm_check,
            "ar_max_dev_m": max_abs_dev(during),
            "ar_stop_dev_m": final_dev if stop_t is not None else None,
            "stop_time_s": stop_t,
            "attack_state": self.parts.attack.state() if self.parts.attack is not None else None,
            "traffic_vehicles": len(self.parts.traffic.cars) if self.parts.traffic is not None else None,
            "hit_vehicle": self.hit, "odometry_bias_rad_per_m": self.parts.defense.odometry_bias(),
        })

    def write_outputs(self, out_dir: Path, result: RunResult, title_suffix: str = "", figures: bool = True) -> None:
        """summary.json, trajectory.csv, traffic.csv (with traffic), birdseye.png and ar_fusion.png (and camera.mp4,
        run.mcap when recorded) of a finished run; without `figures`, believed.csv instead of the figures, which
        `ld3 figures` draws from the folder later."""
        sc, traffic = self.sc, self.parts.traffic
        write_trajectory(out_dir / "trajectory.csv", result.rows)
        if self.parts.traffic is not None:
            self.traffic_log.write(out_dir / "traffic.csv")
        result.record.write(out_dir / "summary.json")
        if not figures:
            write_believed(out_dir / BELIEVED, result.believed_xy)
        else:
            attack = self.parts.attack
            save_run_figures(out_dir, result.rows, FigureInputs(
                self.parts.track, self.parts.lane_width, self.monitor.straddle_dev, result.believed_xy,
                result.summary["detection_time_s"], result.stop_t,
                f"{sc.name} · {sc.track} · defense {sc.defense} · {result.summary['consequence']}" + title_suffix,
                fusion_title(sc.name, sc.track, attack), attack.start_time if attack is not None else None,
                self.parts.defense.alarm_threshold, self.traffic_log.paths() if traffic is not None else None,
                (traffic.length, traffic.width) if traffic is not None else (0, 0)))
        if self.parts.video is not None:
            self.parts.video.write(out_dir / "camera.mp4")
        if self.parts.recording is not None:
            path = np.array([(r.x, r.y) for r in result.rows]).reshape(-1, 2)
            self.parts.recording.set_lane_lines(ego_lane_lines(self.parts.track.lanes[self.parts.lane], path))
            self.parts.recording.write(out_dir / "run.mcap")

    def close(self) -> None:
        if self.parts.video is not None:
            self.parts.video.close()
        if self.parts.world is not None:
            self.parts.world.close()
        if self.parts.streamer is not None:
            self.parts.streamer.close()


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
             progress: bool = False, render: bool | None = None, tracking: bool | None = None,
             figures: bool = True) -> RunResult:
    """Run `sc` and write its outputs into `out_dir`, a folder the caller made and owns (a campaign's
    temporary run folder), or nowhere; without `figures`, believed.csv instead of the figures
    (`SimRun.write_outputs`)."""
    sim = SimRun(sc, render=render, video=video, record=record, tracking=tracking)
    try:
        result = sim.run(progress=progress)
        if out_dir is not None:
            sim.write_outputs(out_dir, result, figures=figures)
        return result
    finally:
        sim.close()
