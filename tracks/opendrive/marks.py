"""OpenDRIVE road marks ↔ the testbed's lane-line kinds (`tracks.layout.MARKING_KINDS`).

Reading: solid/broken in white (or any colour but yellow) → solid_white/dashed_white; solid yellow →
solid_yellow; broken yellow → dashed_white (no dashed yellow kind); any double line (solid solid, solid broken,
broken solid, broken broken) → double_yellow in yellow, solid_white otherwise; botts dots, grass, curb, edge,
custom and none → none.
"""

from __future__ import annotations

_SINGLE = {"solid": "solid", "broken": "dashed"}
_DOUBLE = {"solid solid", "solid broken", "broken solid", "broken broken"}
_WRITE = {
    "solid_white": ("solid", "standard"),
    "dashed_white": ("broken", "standard"),
    "solid_yellow": ("solid", "yellow"),
    "double_yellow": ("solid solid", "yellow"),
    "none": ("none", "standard"),
}


def line_kind(mark_type: str, color: str) -> str:
    """The lane-line kind of an OpenDRIVE roadMark type and colour."""
    yellow = color == "yellow"
    if mark_type in _DOUBLE:
        return "double_yellow" if yellow else "solid_white"
    if mark_type == "solid":
        return "solid_yellow" if yellow else "solid_white"
    if mark_type == "broken":
        return "dashed_white"
    return "none"


def road_mark(kind: str) -> tuple[str, str]:
    """The OpenDRIVE (type, color) of a lane-line kind."""
    return _WRITE[kind]
