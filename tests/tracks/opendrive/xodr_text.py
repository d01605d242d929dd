"""OpenDRIVE text written by hand for the reader's tests: one road per call, every lane's width a cubic."""

from __future__ import annotations

Width = tuple[float, float, float, float]  # a, b, c, d of one width record from the section start


def geometry(s: float, x: float, y: float, hdg: float, length: float, shape: str) -> str:
    return f'<geometry s="{s}" x="{x}" y="{y}" hdg="{hdg}" length="{length}">{shape}</geometry>'


def _lane(lane_id: int, widths: list[tuple[float, Width]], mark: str, kind: str = "driving") -> str:
    records = "".join(f'<width sOffset="{s}" a="{a}" b="{b}" c="{c}" d="{d}"/>' for s, (a, b, c, d) in widths)
    return f'<lane id="{lane_id}" type="{kind}">{records}<roadMark sOffset="0" type="{mark}" color="standard"/></lane>'


def section(s: float, right: list[list[tuple[float, Width]]], left: list[list[tuple[float, Width]]] = (),
            marks: tuple[str, ...] = ()) -> str:
    """A lane section: `right[k]` the width records of lane −(k+1), `left[k]` of lane k+1; `marks[k]` the road
    mark of right lane k+1's outer border (default broken between lanes, solid outside)."""
    marks = marks or tuple("broken" if k < len(right) - 1 else "solid" for k in range(len(right)))
    rights = "".join(_lane(-(k + 1), w, marks[k]) for k, w in enumerate(right))
    lefts = "".join(_lane(k + 1, w, "solid") for k, w in enumerate(left))
    centre = '<center><lane id="0" type="none"><roadMark sOffset="0" type="solid" color="yellow"/></lane></center>'
    return f'<laneSection s="{s}"><left>{lefts}</left>{centre}<right>{rights}</right></laneSection>'


def road(road_id: str, length: float, geometries: list[str], sections: list[str], junction: str = "-1",
         link: str = "", lane_offset: str = "") -> str:
    return (f'<road id="{road_id}" length="{length}" junction="{junction}" rule="RHT"><link>{link}</link>'
            f'<planView>{"".join(geometries)}</planView><lanes>{lane_offset}{"".join(sections)}</lanes></road>')


def document(*elements: str, minor: int = 6) -> str:
    return (f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="{minor}" name="test"/>'
            f'{"".join(elements)}</OpenDRIVE>')


def constant(width: float) -> list[tuple[float, Width]]:
    return [(0.0, (width, 0.0, 0.0, 0.0))]
