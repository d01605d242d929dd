"""Micro-benchmark of semantic-map queries: µs per `lane_dev` call, as a vehicle would issue them.

The query stream follows the ego lane at ~10 m/s sampled at 100 Hz with lateral wander of ±1.5 m (the
warm path), plus a set of independent random poses on the road (the cold path, no locality).
"""

from __future__ import annotations

import time

import numpy as np

from tracks.pose import Pose
from tracks.road import Track
from tracks.semantic_map import TrackMap


def _timed(query, poses: list[Pose]) -> np.ndarray:
    out = np.empty(len(poses))
    for k, pose in enumerate(poses):
        t0 = time.perf_counter()
        query(pose)
        out[k] = time.perf_counter() - t0
    return out * 1e6


def map_query_benchmark(track: Track, n: int = 20000, seed: int = 0) -> dict[str, float]:
    """Median and 99th-percentile µs per `lane_dev` query, warm (driving) and cold (random) streams."""
    rng = np.random.default_rng(seed)
    lane = track.lanes[track.ego_lane]
    s_drive = 5.0 + np.arange(n) * 0.1 % max(track.length - 10.0, 1.0)
    wander = 1.5 * np.sin(s_drive / 37.0)
    drive = [Pose(*lane.position(s, lat), lane.heading_at(s)) for s, lat in zip(s_drive, wander, strict=True)]
    s_rand = rng.uniform(1.0, track.length - 1.0, n // 4)
    l_rand = rng.uniform(-0.5, 0.5, n // 4) * lane.width
    scatter = [Pose(*lane.position(s, lat), 0.0) for s, lat in zip(s_rand, l_rand, strict=True)]
    warm = _timed(TrackMap(track).lane_dev, drive)
    cold = _timed(TrackMap(track).lane_dev, scatter)
    return {
        "median_us": float(np.median(warm)),
        "p99_us": float(np.percentile(warm, 99)),
        "cold_median_us": float(np.median(cold)),
        "cold_p99_us": float(np.percentile(cold, 99)),
    }
