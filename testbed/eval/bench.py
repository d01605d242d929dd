"""Benchmarks (`ld3 bench ...`), not tests: the closed loop's real-time factor and where its time goes,
semantic-map queries, and the defense's per-update cost. Numbers depend on the machine; they are printed,
never asserted.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

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


def bench_loop(seconds: float = 20.0, scenario: str = "urban-straight", detector: str = "neural") -> dict[str, Any]:
    """Closed loop with the camera rendered at 20 Hz on one core: real-time factor and time split."""
    from testbed.eval.runner import SimRun
    from testbed.eval.scenario import load_scenario

    torch.set_num_threads(1)
    sc = load_scenario(scenario).with_overrides(duration=seconds, detector=detector)
    sim = SimRun(sc, render=True)
    timer = SectionTimer()
    timer.wrap(sim.world, "step", "physics")
    timer.wrap(sim.camera, "render", "rendering")
    timer.wrap(sim.streamer, "update", "tile streaming")
    if sim.detector is not None:
        timer.wrap(sim.detector, "detect", "lane detection")
    for obj, name in ((sim.loop.planner, "plan"), (sim.loop.lateral, "update"), (sim.loop.longitudinal, "update")):
        timer.wrap(obj, name, "control")
    timer.wrap(sim.localization, "step", "localization")
    try:
        result = sim.run()
    finally:
        sim.close()
    wall = result.summary["wall_time_s"]
    split = {k: round(v / wall, 4) for k, v in sorted(timer.seconds.items())}
    split["rest"] = round(1.0 - sum(split.values()), 4)
    return {
        "scenario": scenario, "detector": detector, "resolution": f"{sim.rig.width}x{sim.rig.height}",
        "sim_time_s": result.summary["sim_time_s"], "wall_time_s": round(wall, 3),
        "real_time_factor": round(result.summary["real_time_factor"], 2), "time_fraction": split,
        "tile_render_resets": sim.streamer.resets,
    }


def run(what: str, seconds: float = 20.0, detector: str = "neural") -> dict[str, Any]:
    if what == "loop":
        return bench_loop(seconds, detector=detector)
    if what == "map":
        from tracks.bench import map_query_benchmark
        from tracks.presets import load_track

        return {name: map_query_benchmark(load_track(name), 20000) for name in ("urban-curvy", "highway", "local")}
    if what == "defense":
        from testbed.defense.bench import detection_update_benchmark, fusion_update_benchmark

        return {"detection_update": detection_update_benchmark(), "fusion_update": fusion_update_benchmark()}
    raise ValueError(f"unknown benchmark {what!r}")
