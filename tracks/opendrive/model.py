"""The subset of an OpenDRIVE file the reader uses: roads (plan view, lane offset, lane sections with width
polynomials and road marks, links) and junction connections. Lengths in metres, angles in radians."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TypeVar

T = TypeVar("T")


class OpenDriveError(ValueError):
    """An OpenDRIVE file the reader cannot use; the message is one line naming the element and why."""


def latest(records: Iterable[T], start: Callable[[T], float], s: float) -> T | None:
    """The last of `records` (in order of their starts) that starts at or before s (1 nm tolerance)."""
    found = None
    for rec in records:
        if start(rec) <= s + 1e-9:
            found = rec
    return found


@dataclass(frozen=True)
class Poly3:
    """a + b·ds + c·ds² + d·ds³ with ds = s − `s` (the record's start)."""

    s: float
    a: float
    b: float
    c: float
    d: float

    def at(self, s: float) -> float:
        ds = s - self.s
        return self.a + ds * (self.b + ds * (self.c + ds * self.d))


@dataclass(frozen=True)
class Geometry:
    """One planView record: start s, pose (x, y, hdg), length and its shape.

    `kind` is line | arc | spiral | poly3 | paramPoly3; `params` holds that element's attributes
    (curvature; curvStart, curvEnd; a..d; aU..dV and `normalized` for paramPoly3's pRange)."""

    s: float
    x: float
    y: float
    hdg: float
    length: float
    kind: str
    params: dict[str, float]


@dataclass(frozen=True)
class RoadMark:
    """A lane's outer-border marking from `s_offset` (relative to its lane section): type and colour."""

    s_offset: float
    type: str
    color: str


@dataclass(frozen=True)
class LaneRecord:
    """A lane of a section: id (+ left of the reference line, − right, 0 centre), type, width records (sOffset
    relative to the section start), road marks, the ids of the lanes it continues from and into (its `link`),
    and whether it is given by `<border>` records only (not read: refused where a route needs it)."""

    id: int
    type: str
    widths: tuple[Poly3, ...]
    marks: tuple[RoadMark, ...]
    predecessor: int | None = None
    successor: int | None = None
    border_only: bool = False


@dataclass(frozen=True)
class LaneSection:
    """Lanes from road arc length `s` to the next section."""

    s: float
    lanes: tuple[LaneRecord, ...]

    def lane(self, lane_id: int) -> LaneRecord | None:
        return next((ln for ln in self.lanes if ln.id == lane_id), None)


@dataclass(frozen=True)
class Link:
    """A road's predecessor or successor: a road (with the contact point `start`/`end`) or a junction."""

    element_type: str
    element_id: str
    contact_point: str | None


@dataclass(frozen=True)
class Road:
    """One `<road>`: id, length, the junction it belongs to ('-1' for none), traffic rule (RHT/LHT), plan view,
    lane offset records, lane sections and links."""

    id: str
    length: float
    junction: str
    rule: str
    geometries: tuple[Geometry, ...]
    lane_offsets: tuple[Poly3, ...]
    sections: tuple[LaneSection, ...]
    predecessor: Link | None
    successor: Link | None

    def section_at(self, s: float) -> LaneSection:
        """The lane section that holds arc length s (the last whose start is at or before it)."""
        return latest(self.sections, lambda sec: sec.s, s) or self.sections[0]

    def lane_offset_at(self, s: float) -> float:
        """Lateral shift (m, + left) of the centre lane from the reference line at s."""
        found = latest(self.lane_offsets, lambda rec: rec.s, s)
        return 0.0 if found is None else found.at(s)


@dataclass(frozen=True)
class Connection:
    """A junction connection: traffic from `incoming` enters `connecting` (a direct junction's `linkedRoad`) at
    its `contact_point` end; `lane_links` map a lane of `incoming` to the lane it enters."""

    incoming: str
    connecting: str
    contact_point: str
    lane_links: tuple[tuple[int, int], ...] = ()


@dataclass(frozen=True)
class Junction:
    """A junction: its connections; `direct` when they join roads outside it (OpenDRIVE 1.7 `type="direct"`)."""

    id: str
    connections: tuple[Connection, ...]
    direct: bool = False


@dataclass
class OpenDrive:
    """A parsed file: its revision, roads and junctions by id, in file order, and the ego lane the file names
    for its routes' first road (`<userData code="ld3:egoLane">` in the header, written by the exporter)."""

    source: str
    revision: tuple[int, int]
    ego_lane: int | None = None
    roads: dict[str, Road] = field(default_factory=dict)
    junctions: dict[str, Junction] = field(default_factory=dict)
