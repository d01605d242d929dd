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


class SectionTimer:
    """Accumulates wall time per named section by wrapping bound methods of live objects."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    def wrap(self, obj: object, method: str, section: str) -> None:
        inner: Callable[..., Any] = getattr(obj, method)

        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                self.seconds[section] += time.perf_counter() - t0

        setattr(obj, method, timed)


def one_core() -> None:
    """Keep torch and OpenCV on the calling thread, as the benchmarks' "one core" requires."""
    torch.set_num_threads(1)
    cv2.setNumThreads(1)


def bench_loop(seconds: float = 20.0, scenario: str = "urban-straight", detector: str = "neural",
               ground: str = "canvas") -> dict[str, Any]:
    """Closed loop with the camera rendered at 20 Hz on one core: real-time factor (wall clock, and process
    CPU time, which a busy machine disturbs less) and the split of wall time between the parts."""
    from testbed.eval.runner import SimRun
    from testbed.eval.scenario import load_scenario

    one_core()
    sc = load_scenario(scenario).with_overrides(duration=seconds, detector=detector)
    sim = SimRun(sc, render=True, ground=ground)
    timer = SectionTimer()
    timer.wrap(sim.world, "step", "physics")
    timer.wrap(sim.camera, "render", "rendering")
    timer.wrap(sim.streamer, "update", "tile streaming")
    if sim.detector is not None:
        timer.wrap(sim.detector, "detect", "lane detection")
    driving = sim.loop.driving
    for obj, name in ((driving.planner, "plan"), (driving.lateral, "update"), (driving.longitudinal, "update")):
        timer.wrap(obj, name, "control")
    timer.wrap(sim.localization, "step", "localization")
    cpu0 = time.process_time()
    try:
        result = sim.run()
    finally:
        sim.close()
    cpu = time.process_time() - cpu0
    wall = result.summary["wall_time_s"]
    split = {k: round(v / wall, 4) for k, v in sorted(timer.seconds.items())}
    split["rest"] = round(1.0 - sum(split.values()), 4)
    return {
        "scenario": scenario, "detector": detector, "ground": ground, "resolution": f"{sim.rig.width}x{sim.rig.height}",
        "sim_time_s": result.summary["sim_time_s"], "wall_time_s": round(wall, 3), "cpu_time_s": round(cpu, 3),
        "real_time_factor": round(result.summary["real_time_factor"], 2),
        "real_time_factor_cpu": round(result.summary["sim_time_s"] / cpu, 2), "time_fraction": split,
        "tile_render_resets": sim.streamer.resets,
        "ground_canvas_recentres": sim.streamer.canvas.rebuilds if sim.streamer.canvas else None,
    }


def bench_render(frames: int = 200, scenario: str = "urban-straight") -> dict[str, Any]:
    """Cost of one camera frame (CPU ms, median and p99) with the road drawn from the ground canvas and as
    TinyRenderer meshes, at the same poses along the ego lane at 12 m/s and 20 Hz, and their ratio."""
    import numpy as np

    from testbed.eval.runner import SimRun
    from testbed.eval.scenario import load_scenario
    from tracks.pose import Pose

    one_core()
    sc = load_scenario(scenario).with_overrides(duration=1.0, detector="oracle")
    out: dict[str, Any] = {"scenario": scenario, "frames": frames}
    for ground in ("canvas", "mesh"):
        sim = SimRun(sc, render=True, ground=ground)
        lane = sim.track.lanes[sim.lane]
        render_ms, stream_ms = [], []
        try:
            for k in range(frames):
                s = 10.0 + 0.6 * k
                pose = Pose(*lane.position(s, 0.2), lane.heading_at(s))
                t0 = time.thread_time()
                sim.streamer.update(pose)
                t1 = time.thread_time()
                sim.camera.render(pose)
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
    return out


def bench_lane_detectors(repeats: int = 10, frames_per_episode: int = 20) -> dict[str, Any]:
    """Per-frame `detect` latency (ms, median and p99, wall and thread CPU time) on one thread (torch, and
    onnxruntime where installed), over frames freshly rendered from held-out seeds in every condition, each
    detected `repeats` times."""
    import numpy as np

    from testbed.camera import CONDITIONS
    from testbed.lane_detection import CameraFrame
    from testbed.perception.classical import ClassicalLaneDetector
    from testbed.perception.dataset import HELD_OUT_SEEDS, Episode, render_episode
    from testbed.perception.neural import NeuralLaneDetector
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
        from testbed.perception.onnx_runtime import OnnxLaneDetector

        detectors["neural-onnx"] = OnnxLaneDetector(threads=1)
    except RuntimeError as exc:  # onnxruntime not installed
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


def run(what: str, seconds: float = 20.0, detector: str = "neural", ground: str = "canvas") -> dict[str, Any]:
    if what == "loop":
        return bench_loop(seconds, detector=detector, ground=ground)
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
