"""A lane as a lateral offset of the road's reference line (highway-env `AbstractLane` style).

Longitudinal coordinate s is the reference line's arc length (shared by all lanes of a road, so lanes
line up at the same s); lateral coordinate l is signed, + left of this lane's centreline as seen in the lane's
direction of travel: along the reference line (`direction` +1), or against it for an oncoming lane (−1, which
is travelled towards decreasing s). Heading and curvature are those of travel too. Offset and width are
constants, or `Profile`s along s where the lane widens or narrows (roads read from OpenDRIVE); the offset is
always measured on the reference line, + left of it.
"""

from __future__ import annotations

import math

from tracks.geometry import ReferenceLine
from tracks.pose import Pose
from tracks.profile import Profile


class Lane:
    """Lane `index` (0 = rightmost) centred `offset` m left of the reference line, `width` m wide, travelled
    along the reference line (`direction` +1) or against it (−1); with profiles, offset and width are nominal
    values and `offset_at`/`width_at` follow the profiles."""

    def __init__(self, reference: ReferenceLine, index: int, offset: float, width: float,
                 profiles: tuple[Profile, Profile] | None = None, direction: int = 1) -> None:
        if direction not in (1, -1):
            raise ValueError(f"lane direction must be +1 or -1, got {direction}")
        self.reference = reference
        self.index = index
        self.offset = offset
        self.width = width
        self.profiles = profiles
        self.direction = direction

    @property
    def oncoming(self) -> bool:
        """True for a lane travelled against the reference line."""
        return self.direction < 0

    @property
    def length(self) -> float:
        return self.reference.length

    def position(self, s: float, lat: float = 0.0) -> tuple[float, float]:
        """World (x, y) of the point at reference arc length s, `lat` metres left of the lane centre."""
        return self.reference.point(s, self.offset_at(s) + self.direction * lat)

    def local_coordinates(self, x: float, y: float) -> tuple[float, float]:
        """(s, l) of a world point: s along the reference line, l signed offset from this lane's centre."""
        s, t = self.reference.project(x, y)
        return s, self.direction * (t - self.offset_at(s))

    def heading_at(self, s: float) -> float:
        """Heading of travel (rad): the reference line's, turned by π for an oncoming lane."""
        return self._travel(self.reference.heading_at(s))

    def centre_at(self, s: float) -> tuple[float, float, float]:
        """`position(s)` and `heading_at(s)` as (x, y, heading) from one reference-line query, to the bit."""
        x, y, h = self.reference.frame(s)
        t = self.offset_at(s) + self.direction * 0.0
        return x - t * math.sin(h), y + t * math.cos(h), self._travel(h)

    def pose_at(self, s: float) -> Pose:
        """The pose on the lane centre at reference arc length s, heading in the direction of travel (one
        reference-line query)."""
        return Pose(*self.centre_at(s))

    def _travel(self, h: float) -> float:
        return h if self.direction > 0 else h + math.pi

    def offset_at(self, s: float) -> float:
        """Offset (m, + left) of the lane centre from the reference line at s."""
        return self.offset if self.profiles is None else self.profiles[0].at(s)

    def width_at(self, s: float) -> float:
        return self.width if self.profiles is None else self.profiles[1].at(s)

    def curvature_at(self, s: float) -> float:
        """Curvature of the lane centreline itself in its direction of travel (1/m, + left): k / (1 - k * offset)
        for an offset curve, negated for an oncoming lane."""
        k = self.reference.curvature_at(s)
        return self.direction * k / (1.0 - k * self.offset_at(s))
