"""Town-corner roads for training frames only: two lanes (one each way, or both along the road) turning through
arcs of radius 15–50 m entered without transition curves, as a car turns at a town junction, between straights
of 15–60 m. They are no presets: the campaigns and the closed-loop cells keep their roads. A seed gives one road;
the radius, angle, direction and straight of each corner, the lane widths, markings and kerbs are drawn from it."""

from __future__ import annotations

import math

import numpy as np

from tracks.geometry import Arc, ReferenceLine, Segment, Straight
from tracks.layout import Edge, RoadsideBody
from tracks.pose import Pose
from tracks.road import Track

NAME = "corners"
RADIUS_RANGE_M = (15.0, 50.0)
ANGLE_RANGE_DEG = (35.0, 100.0)
STRAIGHT_RANGE_M = (15.0, 60.0)
LENGTH_M = 900.0
MAX_HEADING_DEG = 100.0  # a corner that would turn the road further from its start heading turns the other way
CLEARANCE_M = 30.0  # the least distance between parts of the road more than CLEARANCE_ALONG_M apart along it
CLEARANCE_ALONG_M = 80.0
DRAWS = 100  # layouts drawn for a seed before one that keeps its clearance is given up
CURB = RoadsideBody("curb", gap=0.10, thickness=0.30, height=0.15)


def corner_road(seed: int) -> Track:
    """The corner road of `seed` (see the module): the first layout drawn whose parts keep `CLEARANCE_M` from each
    other (a road that came back near itself would put a pose on two parts of it)."""
    rng = np.random.default_rng([seed, sum(map(ord, NAME))])
    for _ in range(DRAWS):
        reference = _layout(rng)
        s = np.arange(0.0, reference.length, 2.0)
        xy = reference.points(s, 0.0)
        apart = np.abs(s[:, None] - s[None, :]) > CLEARANCE_ALONG_M
        if np.min(np.linalg.norm(xy[:, None] - xy[None, :], axis=-1)[apart]) >= CLEARANCE_M:
            break
    else:
        raise ValueError(f"no corner road of seed {seed} keeps {CLEARANCE_M} m between its parts in {DRAWS} draws")
    oncoming = int(rng.random() < 0.5)
    centre = str(rng.choice(["double_yellow", "solid_yellow"])) if oncoming else "dashed_white"
    widths = [float(rng.uniform(3.0, 3.6)), float(rng.uniform(3.0, 3.6))]
    edge = Edge("curb", paved=0.30, ground=str(rng.choice(["concrete", "grass"])), bodies=(CURB,))
    return Track(NAME, seed, "two-lane town road of tight corners (R 15-50 m, no transition curves), training only",
                 reference, widths, ["solid_white", centre, "solid_white"], edge, edge, oncoming=oncoming)


def _layout(rng: np.random.Generator) -> ReferenceLine:
    """A run-in straight, then corners and the straights after them until `LENGTH_M`."""
    segments: list[Segment] = [Straight(float(rng.uniform(30.0, 60.0)))]
    length, heading = segments[0].length, 0.0
    while length < LENGTH_M:
        radius = float(rng.uniform(*RADIUS_RANGE_M))
        angle = math.radians(float(rng.uniform(*ANGLE_RANGE_DEG)))
        sign = 1.0 if rng.random() < 0.5 else -1.0
        if abs(heading + sign * angle) > math.radians(MAX_HEADING_DEG):
            sign = -sign
        straight = float(rng.uniform(*STRAIGHT_RANGE_M))
        segments += [Arc(sign * radius, radius * angle), Straight(straight)]
        heading += sign * angle
        length += radius * angle + straight
    return ReferenceLine(Pose(0.0, 0.0, 0.0), segments)
