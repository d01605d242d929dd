"""A lane as a lateral offset of the road's reference line (highway-env `AbstractLane` style).

Longitudinal coordinate s is the reference line's arc length (shared by all lanes of a road, so lanes
line up at the same s); lateral coordinate l is signed, + left of this lane's centreline. Offset and width
are constants, or `Profile`s along s where the lane widens or narrows (roads read from OpenDRIVE).
"""

from __future__ import annotations

from tracks.geometry import ReferenceLine
from tracks.profile import Profile


class Lane:
    """Lane `index` (0 = rightmost) centred `offset` m left of the reference line, `width` m wide; with
    profiles, those are nominal values and `offset_at`/`width_at` follow the profiles."""

    def __init__(self, reference: ReferenceLine, index: int, offset: float, width: float,
                 profiles: tuple[Profile, Profile] | None = None) -> None:
        self.reference = reference
        self.index = index
        self.offset = offset
        self.width = width
        self.profiles = profiles

    @property
    def length(self) -> float:
        return self.reference.length

    def position(self, s: float, lat: float = 0.0) -> tuple[float, float]:
        """World (x, y) of the point at reference arc length s, `lat` metres left of the lane centre."""
        return self.reference.point(s, self.offset_at(s) + lat)

    def local_coordinates(self, x: float, y: float) -> tuple[float, float]:
        """(s, l) of a world point: s along the reference line, l signed offset from this lane's centre."""
        s, t = self.reference.project(x, y)
        return s, t - self.offset_at(s)

    def heading_at(self, s: float) -> float:
        return self.reference.heading_at(s)

    def offset_at(self, s: float) -> float:
        """Offset (m, + left) of the lane centre from the reference line at s."""
        return self.offset if self.profiles is None else self.profiles[0].at(s)

    def width_at(self, s: float) -> float:
        return self.width if self.profiles is None else self.profiles[1].at(s)

    def curvature_at(self, s: float) -> float:
        """Curvature of the lane centreline itself (1/m, + left): k / (1 - k * offset) for an offset curve."""
        k = self.reference.curvature_at(s)
        return k / (1.0 - k * self.offset_at(s))
