"""Benchmarks (`ld3 bench ...`), not tests: the closed loop's real-time factor and where its time goes,
semantic-map queries, the lane detectors' per-frame latency, and the defense's per-update cost. Numbers
depend on the machine; they are printed, never asserted.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import cv2
import torch
from threadpoolctl import threadpool_limits

from testbed.errors import UserError


class SectionTimer:
    """Accumulates wall time per named section by wrapping bound methods of live objects. A wrapped call made
    inside another counts for its own section only (exclusive time), so the sections add up to the total."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self._clock = clock
        self._inner: list[float] = [0.0]  # time spent in nested wrapped calls, per open call

    def wrap(self, obj: object, method: str, section: str) -> None:
        inner: Callable[..., Any] = getattr(obj, method)
        nested, clock = self._inner, self._clock

        def timed(*args: Any, **kwargs: Any) -> Any:
            nested.append(0.0)
            t0 = clock()
            try:
                return inner(*args, **kwargs)
            finally:
                elapsed = clock() - t0
                self.seconds[section] += elapsed - nested.pop()
                nested[-1] += elapsed

        setattr(obj, method, timed)

    def wrap_all(self, obj: object, methods: tuple[str, ...], section: str) -> None:
        for method in methods:
            self.wrap(obj, method, section)


def one_core() -> None:
    """Keep torch, OpenCV and the BLAS and OpenMP pools (numpy's OpenBLAS spreads even a 7 × 7 `dot` over two
    threads) on the calling thread, as the benchmarks' "one core" requires."""
    torch.set_num_threads(1)
    cv2.setNumThreads(1)
    threadpool_limits(limits=1)


LOOP_SECTIONS = ("physics", "vehicle actuation", "localization", "map", "control", "defense", "attack",
                 "logging", "consequence monitor", "render", "ground canvas", "image effects", "tile streaming",
                 "detector", "traffic")
"""The parts `bench loop` splits the loop's wall time into (plus `rest`: the loop's own glue). The camera's
frame is `render` (TinyRenderer's picture of the roadside and traffic boxes, drawn by its compiled clone where it is
built, and compositing), `ground canvas` (the road drawn from the canvas) and `image effects` (the condition's sky,
exposure and noise)."""


TIMED = ("the loop, from the first tick to the last; building the run (its world, and its detector, whose first build "
         "in a process also exports and loads the network and infers one frame) is not timed")
"""What `bench loop`'s wall and CPU clocks cover, as its output says."""


def _instrument(sim, timer: SectionTimer) -> None:
    """Wrap every part of a built SimRun in its LOOP_SECTIONS section."""
    loop, track = sim.loop, sim.parts.track
    timer.wrap(sim.parts.world, "step", "physics")
    timer.wrap(sim.parts.world, "update_obstacles", "tile streaming")
    timer.wrap_all(sim.parts.world.vehicle, ("actuate", "sense", "apply_road_load"), "vehicle actuation")
    timer.wrap(sim.parts.chassis, "read", "vehicle actuation")
    timer.wrap(sim.parts.localization, "step", "localization")
    timer.wrap_all(sim.parts.smap, ("project", "lane_dev", "lane_width", "lane_point", "lane_curvature"), "map")
    timer.wrap_all(track, ("road_surface_contains", "edge_kind_at", "lidar_feature_quality"), "map")
    timer.wrap(track.reference, "project", "map")
    timer.wrap_all(loop.driving.planner, ("plan", "start_stop"), "control")
    timer.wrap(loop.driving.lateral, "update", "control")
    timer.wrap(loop.driving.longitudinal, "update", "control")
    timer.wrap_all(sim.parts.defense, ("on_gnss", "on_lane_detection", "pose_for_control", "on_command", "status"),
                   "defense")
    timer.wrap(loop.ld_dev, "update", "defense")
    if sim.parts.attack is not None:
        timer.wrap_all(sim.parts.attack, ("spoof_gnss", "tamper_msf", "tamper_ld", "state"), "attack")
        timer.wrap(loop, "_attacker_view", "attack")
    timer.wrap(loop, "_record", "logging")
    timer.wrap(sim, "_edge_beyond", "consequence monitor")
    timer.wrap(sim.run_loop, "_stood_still", "consequence monitor")
    timer.wrap(sim.monitor, "observe", "consequence monitor")
    timer.wrap(sim.parts.world, "contact_kinds", "consequence monitor")
    if sim.parts.camera is not None:
        timer.wrap(sim.parts.camera, "capture", "render")
        timer.wrap(sim.parts.camera.effects, "apply", "image effects")
        timer.wrap(sim.parts.streamer, "update", "tile streaming")
        if sim.parts.streamer.canvas is not None:
            timer.wrap(sim.parts.streamer.canvas, "view", "ground canvas")
    if sim.parts.detector is not None:
        timer.wrap(sim.parts.detector, "detect", "detector")
    if sim.parts.tracker is not None:
        timer.wrap(sim.parts.tracker, "update", "detector")
    if sim.parts.traffic is not None:
        timer.wrap(sim.parts.traffic, "advance", "traffic")
        timer.wrap_all(sim.parts.world, ("place_traffic", "traffic_touching"), "traffic")
        timer.wrap(sim.traffic_log, "add", "traffic")


class StepSimulationClock:
    """Within the block, every `pybullet.stepSimulation` call's wall time is summed into `seconds`: the physics of
    the loop's own world (its streamed roadside bodies and the car as driven), without the loop around it."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def __enter__(self) -> StepSimulationClock:
        import pybullet as pb

        self._step = step = pb.stepSimulation
        clock = time.perf_counter

        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = clock()
            try:
                return step(*args, **kwargs)
            finally:
                self.seconds += clock() - t0

        pb.stepSimulation = timed
        return self

    def __exit__(self, *exc: object) -> None:
        import pybullet as pb

        pb.stepSimulation = self._step


def _bare_physics(sc, steps: int) -> dict[str, float]:
    """`stepSimulation` alone, `steps` times, in a fresh world of the scenario with its car rolling at the
    scenario speed under a constant command: wall and CPU seconds."""
    import pybullet as pb

    from testbed.eval.run.build import physics_world_for
    from tracks.presets import load_track
    from vehicles.params import get_vehicle

    track = load_track(sc.track)
    lane = sc.lane if sc.lane is not None else track.ego_lane
    start = track.start_pose(lane, sc.start_s)
    world = physics_world_for(sc, track, get_vehicle(sc.vehicle), start)
    try:
        world.vehicle.reset_pose(start, sc.speed)
        world.vehicle.actuate(world.dt)
        client = world.client
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            pb.stepSimulation(physicsClientId=client)
        return {"wall_s": time.perf_counter() - wall0, "cpu_s": time.process_time() - cpu0}
    finally:
        world.close()


def bench_loop(seconds: float = 20.0, scenario: str = "urban-straight", detector: str = "neural",
               ground: str = "canvas", camera: bool = True, speed: float | None = None,
               localization: str | None = None, traffic: int | None = None,
               settings: list[str] | None = None) -> dict[str, Any]:
    """The closed loop on one core, with the camera rendered at its rate or without a camera, `traffic` cars
    of the scenario's `[traffic]` (default: its own count) and the scenario `settings` (`--set`): its real-time
    factor (wall clock, and process CPU time, which a busy machine disturbs less), the bare-physics
    real-time factor of the same world and car (`stepSimulation` alone, as many steps), their ratio, and
    the split of wall time between the loop's parts (LOOP_SECTIONS) from a second, instrumented run. That run
    also times `stepSimulation` inside the loop (`in_loop_physics_real_time_factor`): the fresh world of the
    bare figure has none of the roadside bodies the loop streams around the car, so its steps are cheaper;
    `ratio_to_in_loop_physics` is the loop's real-time factor over the in-loop one."""
    from testbed.eval.run.runner import SimRun
    from testbed.eval.run.scenario import ScenarioError, apply_settings, load_scenario
    from testbed.perception.detectors.registry import DETECTORS
    from testbed.registry import Capability

    one_core()
    sc = load_scenario(scenario).with_overrides(duration=seconds, detector=detector, speed=speed,
                                                localization=localization)
    if traffic is not None or settings:
        sc = apply_settings(sc, [*([f"traffic.vehicles={traffic}"] if traffic is not None else []),
                                 *(settings or [])])
    if not camera and Capability.CAMERA_IMAGE in DETECTORS.get(sc.detector).provides:
        raise ScenarioError(f"detector {sc.detector!r} reads the camera: use --camera on, or a detector that "
                            f"does not (--detector oracle or none)")

    def build() -> SimRun:
        return SimRun(sc, render=camera, ground=ground)

    sim = build()
    cpu0 = time.process_time()
    try:
        result = sim.run()
    finally:
        sim.close()
    cpu = time.process_time() - cpu0
    sim_time, wall = result.record.sim_time_s, result.record.wall_time_s
    physics_hz = sc.rates.physics_hz
    steps = round(sim_time * physics_hz)
    bare = _bare_physics(sc, steps)

    timed, timer = build(), SectionTimer()
    _instrument(timed, timer)
    try:
        with StepSimulationClock() as in_loop:
            timed_wall = timed.run().record.wall_time_s
    finally:
        timed.close()
    split = {k: round(timer.seconds.get(k, 0.0) / timed_wall, 4) for k in LOOP_SECTIONS}
    split["rest"] = round(1.0 - sum(split.values()), 4)
    rtf, bare_rtf = sim_time / wall, sim_time / bare["wall_s"]
    out: dict[str, Any] = {
        "scenario": scenario, "track": sc.track, "vehicle": sc.vehicle, "speed_mps": sc.speed,
        "localization": sc.localization, "detector": sc.detector, "camera": camera, "physics_hz": physics_hz,
        "control_hz": sc.rates.control_hz, "traffic_vehicles": sc.traffic.vehicles, "sim_time_s": sim_time,
        "physics_steps": steps, "wall_time_s": round(wall, 3), "cpu_time_s": round(cpu, 3),
        "real_time_factor": round(rtf, 2), "real_time_factor_cpu": round(sim_time / cpu, 2),
        "bare_physics_real_time_factor": round(bare_rtf, 2),
        "bare_physics_real_time_factor_cpu": round(sim_time / bare["cpu_s"], 2),
        "ratio_to_bare_physics": round(rtf / bare_rtf, 3),
        "ratio_to_bare_physics_cpu": round(bare["cpu_s"] / cpu, 3),
        "in_loop_physics_real_time_factor": round(sim_time / in_loop.seconds, 2),
        "ratio_to_in_loop_physics": round(in_loop.seconds / wall, 3),
        "instrumented_real_time_factor": round(sim_time / timed_wall, 2), "time_fraction": split,
        "timed": TIMED,
    }
    if camera:
        out |= {"ground": ground, "resolution": f"{sim.parts.rig.width}x{sim.parts.rig.height}",
                "boxes_drawn_by": "tinyrenderer" if sim.parts.streamer.boxes is None else "clone",
                "tile_render_resets": sim.parts.streamer.resets,
                "ground_canvas_recentres": sim.parts.streamer.canvas.rebuilds if sim.parts.streamer.canvas else None}
    return out


def bench_render(frames: int = 200, scenario: str = "urban-straight") -> dict[str, Any]:
    """Cost of one camera frame (CPU ms, median and p99) with the road drawn from the ground canvas and as
    TinyRenderer meshes, at the same poses along the ego lane at 12 m/s and 20 Hz, and their ratio."""
    import numpy as np

    from testbed.eval.run.runner import SimRun
    from testbed.eval.run.scenario import load_scenario
    from tracks.pose import Pose

    one_core()
    sc = load_scenario(scenario).with_overrides(duration=1.0, detector="oracle")
    out: dict[str, Any] = {"scenario": scenario, "frames": frames}
    for ground in ("canvas", "mesh"):
        sim = SimRun(sc, render=True, ground=ground)
        lane = sim.parts.track.lanes[sim.parts.lane]
        render_ms, stream_ms = [], []
        try:
            for k in range(frames):
                s = 10.0 + 0.6 * k
                pose = Pose(*lane.position(s, 0.2), lane.heading_at(s))
                t0 = time.thread_time()
                sim.parts.streamer.update(pose)
                t1 = time.thread_time()
                sim.parts.camera.render(pose)
                t2 = time.thread_time()
                stream_ms.append(1e3 * (t1 - t0))
                render_ms.append(1e3 * (t2 - t1))
        finally:
            sim.close()
        out[ground] = {"render_ms_median": round(float(np.median(render_ms)), 3),
                       "render_ms_p99": round(float(np.percentile(render_ms, 99)), 3),
                       "streaming_ms_mean": round(float(np.mean(stream_ms)), 3)}
    ratio = out["mesh"]["render_ms_median"] / out["canvas"]["render_ms_median"]
    out["render_speedup_mesh_over_canvas"] = round(ratio, 2)
    out["boxes"] = bench_boxes(frames, scenario)
    return out


def bench_boxes(frames: int = 200, scenario: str = "urban-straight") -> dict[str, Any] | None:
    """Cost of the camera's picture of the roadside (and traffic) boxes alone (CPU ms per frame, median and p99):
    TinyRenderer's compiled clone against TinyRenderer itself, in one process, at the same poses (as
    `bench_render`'s), each scene streamed by its own streamer; whether the pictures were all the same bytes. None
    where the clone is not built."""
    import numpy as np

    from testbed.camera import FrontCamera
    from testbed.eval.run.runner import SimRun
    from testbed.eval.run.scenario import load_scenario
    from testbed.tiny_boxes import kernel
    from testbed.world import TileStreamer
    from tracks.pose import Pose

    if kernel() is None:
        return None
    one_core()
    sim = SimRun(load_scenario(scenario).with_overrides(duration=1.0, detector="oracle"), render=False)
    track, condition, rig = sim.parts.track, sim.parts.condition, sim.parts.rig
    lane = track.lanes[sim.parts.lane]
    sim.close()
    streamers = {"clone": TileStreamer(track, condition.lighting),
                 "tinyrenderer": TileStreamer(track, condition.lighting, clone=False)}
    cameras = {name: FrontCamera(s, rig, condition, np.random.default_rng(0)) for name, s in streamers.items()}
    times: dict[str, list[float]] = {name: [] for name in streamers}
    same = True
    try:
        for k in range(frames):
            s = 10.0 + 0.6 * k
            pose = Pose(*lane.position(s, 0.2), lane.heading_at(s))
            pictures = []
            for name, camera in cameras.items():
                streamers[name].update(pose)
                t0 = time.thread_time()
                pictures.append(camera.scene(pose))
                times[name].append(1e3 * (time.thread_time() - t0))
            (rgba_a, empty_a), (rgba_b, empty_b) = pictures
            same &= bool(np.array_equal(rgba_a, rgba_b) and np.array_equal(empty_a, empty_b))
    finally:
        for streamer in streamers.values():
            streamer.close()
    out: dict[str, Any] = {name: {"ms_median": round(float(np.median(t)), 3),
                                  "ms_p99": round(float(np.percentile(t, 99)), 3)} for name, t in times.items()}
    out["speedup"] = round(out["tinyrenderer"]["ms_median"] / out["clone"]["ms_median"], 2)
    out["identical"] = same
    return out


def bench_lane_detectors(repeats: int = 10, frames_per_episode: int = 20) -> dict[str, Any]:
    """Per-frame `detect` latency (ms, median and p99, wall and thread CPU time) on one thread (torch as
    `neural`, and onnxruntime, the `neural` detector's default runtime, as `neural-onnx` where installed), over
    frames freshly rendered from held-out seeds in every condition, each detected `repeats` times."""
    import numpy as np

    from testbed.conditions import CONDITIONS
    from testbed.lane_detection import CameraFrame
    from testbed.perception.detectors.classical import ClassicalLaneDetector
    from testbed.perception.detectors.neural import NeuralLaneDetector
    from testbed.perception.training.dataset import Episode, render_episode
    from testbed.perception.training.seeds import HELD_OUT_SEEDS
    from vehicles.camera_rig import CameraRig
    from vehicles.params import get_vehicle

    one_core()
    eps = [Episode(preset, HELD_OUT_SEEDS[k], cond)
           for k, (preset, cond) in enumerate(zip(("urban-straight", "highway", "urban-curvy", "local", "slr",
                                                    "urban-straight"), CONDITIONS, strict=True))]
    images = [image for ep in eps for image, _ in render_episode(ep, frames_per_episode)]
    detectors = {"neural": NeuralLaneDetector(threads=1)}
    out: dict[str, Any] = {"frames": len(images), "repeats": repeats, "torch_threads": torch.get_num_threads()}
    try:
        from testbed.perception.detectors.onnx_runtime import OnnxLaneDetector

        detectors["neural-onnx"] = OnnxLaneDetector(threads=1)
    except UserError as exc:  # onnxruntime not installed
        out["neural-onnx"] = str(exc)
    detectors["classical"] = ClassicalLaneDetector(CameraRig(get_vehicle("sedan").camera))
    for name, det in detectors.items():
        for image in images[:10]:
            det.detect(CameraFrame(0.0, image))  # warm-up
        wall, cpu = [], []
        for _ in range(repeats):
            for image in images:
                t0, c0 = time.perf_counter(), time.thread_time()
                det.detect(CameraFrame(0.0, image))
                wall.append(1e3 * (time.perf_counter() - t0))
                cpu.append(1e3 * (time.thread_time() - c0))
        out[name] = {"ms_median": round(float(np.median(wall)), 3), "ms_p99": round(float(np.percentile(wall, 99)), 3),
                     "cpu_ms_median": round(float(np.median(cpu)), 3),
                     "cpu_ms_p99": round(float(np.percentile(cpu, 99)), 3)}
    return out


def run(what: str, seconds: float = 20.0, detector: str = "neural", ground: str = "canvas", camera: bool = True,
        scenario: str = "urban-straight", speed: float | None = None, localization: str | None = None,
        traffic: int | None = None, settings: list[str] | None = None) -> dict[str, Any]:
    """Run benchmark `what`; the other arguments are `loop`'s."""
    if what == "loop":
        return bench_loop(seconds, scenario, detector, ground, camera, speed, localization, traffic, settings)
    if what == "render":
        return bench_render()
    if what == "ld":
        return bench_lane_detectors()
    if what == "map":
        from tracks.bench import map_query_benchmark
        from tracks.presets import load_track

        return {name: map_query_benchmark(load_track(name), 20000) for name in ("urban-curvy", "highway", "local")}
    if what == "defense":
        from testbed.defense.bench import detection_update_benchmark, fusion_update_benchmark

        return {"detection_update": detection_update_benchmark(), "fusion_update": fusion_update_benchmark()}
    raise ValueError(f"unknown benchmark {what!r}")
