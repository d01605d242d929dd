"""Fixtures: a hand-built two-lane track with an arc, an intersection and an unmarked edge stretch."""

import pytest

from tracks.geometry import Arc, ReferenceLine, Straight
from tracks.layout import Boundary, Edge, MarkingRun
from tracks.pose import Pose
from tracks.road import Track

LANE_W = 3.5
ARC_R = 100.0  # the arc spans reference s in [200, 260)


@pytest.fixture
def track() -> Track:
    ref = ReferenceLine(Pose(0.0, 0.0, 0.0), [Straight(200.0), Arc(ARC_R, 60.0), Straight(200.0)])
    tr = Track("test", 1, "test road", ref, [LANE_W, LANE_W], ["solid_white", "dashed_white", "solid_yellow"],
               Edge("shoulder", 1.0, "grass"), Edge("shoulder", 1.0, "grass"), intersections=[(400.0, 420.0)])
    runs = [(0.0, 100.0, "solid_white"), (100.0, 150.0, "none"), (150.0, 400.0, "solid_white"),
            (400.0, 420.0, "none"), (420.0, tr.length, "solid_white")]
    tr.boundaries[0] = Boundary(tr.boundaries[0].t, tuple(MarkingRun(*r) for r in runs))
    return tr


def pose_on(track: Track, lane: int, s: float, offset: float = 0.0, dyaw: float = 0.0) -> Pose:
    x, y = track.lanes[lane].position(s, offset)
    return Pose(x, y, track.lanes[lane].heading_at(s) + dyaw)


@pytest.fixture(scope="session")
def heldout_frames() -> list:
    """28 frames rendered now from held-out track seeds (day on a straight road, dusk on the highway)."""
    from testbed.perception.training.dataset import Episode, render_episode
    from testbed.perception.training.seeds import HELD_OUT_SEEDS

    eps = (Episode("urban-straight", HELD_OUT_SEEDS[3], "day"), Episode("highway", HELD_OUT_SEEDS[7], "dusk"))
    return [frame for ep in eps for frame in render_episode(ep, 14)]
