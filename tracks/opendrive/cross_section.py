"""A road's cross section at arc length s on one side of its centre lane: lane borders, types and marks.

Offsets t are measured on the road's reference line, + left; the centre lane sits at the lane offset and
lanes stack outward from it by their width polynomials (sOffset relative to their lane section).
"""

from __future__ import annotations

from typing import NamedTuple

from tracks.opendrive.marks import line_kind
from tracks.opendrive.model import LaneRecord, LaneSection, Road, latest

DRIVABLE = frozenset({"driving", "entry", "exit", "onRamp", "offRamp", "connectingRamp"})  # not bidirectional
CURBSIDE = frozenset({"sidewalk", "curb", "walking"})


class CrossSection(NamedTuple):
    """One side at one s: `borders[0]` is the centre lane's offset, `borders[k]` the outer border of the k-th
    lane out; `ids[k-1]`, `types[k-1]` and `marks[k]` (marks[0]: the centre lane's) belong to the same lanes."""

    borders: list[float]
    types: list[str]
    marks: list[str]
    ids: list[int]

    def group(self, k: int) -> tuple[int, int]:
        """(index of the first, count) of the run of drivable lanes without a gap that holds lane index k."""
        first = k
        while first > 0 and self.types[first - 1] in DRIVABLE:
            first -= 1
        last = k
        while last + 1 < len(self.types) and self.types[last + 1] in DRIVABLE:
            last += 1
        return first, last - first + 1

    def drivable(self) -> tuple[int, int]:
        """(index of the first drivable lane from the centre, how many drivable lanes follow it without a gap);
        (len(types), 0) when there is none."""
        first = next((k for k, kind in enumerate(self.types) if kind in DRIVABLE), len(self.types))
        n = 0
        while first + n < len(self.types) and self.types[first + n] in DRIVABLE:
            n += 1
        return first, n

    def paved_beyond(self, n: int) -> tuple[float, bool]:
        """(width of the lanes beyond the n-th up to any sidewalk or curb, whether one follows)."""
        for k in range(n, len(self.types)):
            if self.types[k] in CURBSIDE:
                return abs(self.borders[k] - self.borders[n]), True
        return abs(self.borders[-1] - self.borders[n]), False


def lane_width(lane: LaneRecord, ds: float) -> float:
    """The lane's width (m, >= 0) at ds from its section's start."""
    rec = latest(lane.widths, lambda w: w.s, ds) or lane.widths[0]
    return max(rec.at(ds), 0.0)


def _mark(lane: LaneRecord | None, ds: float) -> str:
    found = None if lane is None else latest(lane.marks, lambda m: m.s_offset, ds)
    return "none" if found is None else line_kind(found.type, found.color)


def side_lanes(section: LaneSection, side: int) -> list[LaneRecord]:
    """The lanes of `side` (−1 right, +1 left) from the centre outward."""
    return sorted((ln for ln in section.lanes if ln.id * side > 0), key=lambda ln: abs(ln.id))


def cross_section(road: Road, s: float, side: int) -> CrossSection:
    """The cross section of `side` (−1 right, +1 left) of `road` at arc length s."""
    section = road.section_at(s)
    ds = s - section.s
    t = road.lane_offset_at(s)
    borders, types, marks, ids = [t], [], [_mark(section.lane(0), ds)], []
    for lane in side_lanes(section, side):
        t += side * lane_width(lane, ds)
        borders.append(t)
        types.append(lane.type)
        marks.append(_mark(lane, ds))
        ids.append(lane.id)
    return CrossSection(borders, types, marks, ids)
