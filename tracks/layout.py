"""Cross-section vocabulary of a road: lane-line marking runs, road edges and the roadside bodies on them.

Lateral offsets t are measured on the road's reference line (+ left). An edge is described outward from
the outermost lane line: a paved strip (`paved` m: shoulder or gutter), then roadside ground, with
physical bodies (curb, barrier, guardrail, lane divider, trees) whose near face lies `gap` m out.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

MARKING_KINDS = ("solid_white", "dashed_white", "solid_yellow", "double_yellow", "none")
EDGE_KINDS = ("shoulder", "curb", "barrier", "guardrail", "divider", "drop_off", "open")
BODY_KINDS = ("curb", "barrier", "guardrail", "divider", "tree")
GROUND_KINDS = ("grass", "concrete", "dirt", "drop", "asphalt")


@dataclass(frozen=True)
class MarkingRun:
    """Marking `kind` painted on a lane line over reference arc length [s0, s1)."""

    s0: float
    s1: float
    kind: str


@dataclass(frozen=True)
class Boundary:
    """A lane line at lateral offset `t`; `runs` tile [0, length] in order."""

    t: float
    runs: tuple[MarkingRun, ...]

    def kind_at(self, s: float) -> str:
        for run in self.runs:
            if run.s0 <= s < run.s1:
                return run.kind
        return "none"


@dataclass(frozen=True)
class RoadsideBody:
    """A physical body along an edge: near face `gap` m beyond the outer lane line.

    `spacing` = 0 means continuous (chunked into boxes along the edge); otherwise square objects of side
    `thickness` every `spacing` m (trees).
    """

    kind: str
    gap: float
    thickness: float
    height: float
    spacing: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in BODY_KINDS:
            raise ValueError(f"unknown roadside body kind {self.kind!r}")


@dataclass(frozen=True)
class Edge:
    """One side of the road: its kind (what leaving the road there means), paved width beyond the outer
    lane line, the ground beyond the pavement and the bodies standing on it."""

    kind: str
    paved: float
    ground: str
    bodies: tuple[RoadsideBody, ...] = ()
    roadside: float = 4.0

    def __post_init__(self) -> None:
        if self.kind not in EDGE_KINDS:
            raise ValueError(f"unknown edge kind {self.kind!r}")
        if self.ground not in GROUND_KINDS:
            raise ValueError(f"unknown ground kind {self.ground!r}")

    @property
    def extent(self) -> float:
        """Lateral reach beyond the outer lane line that tiles must cover (paved + roadside + bodies)."""
        far = max((b.gap + b.thickness for b in self.bodies), default=0.0)
        return max(self.paved + self.roadside, far + 1.0)


class CollisionBox(NamedTuple):
    """A static box for the physics world: centre (x, y, z), half extents, yaw (rad), kind, tile index."""

    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    yaw: float
    kind: str
    tile: int
