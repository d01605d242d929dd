"""A track: one road of lanes on a reference line, with markings, edges, intersections, a LiDAR
feature-quality profile and the painters of its tiles. The lanes run along the reference line, except the
leftmost `oncoming` ones, which carry the other direction's traffic (a two-way road). A track is data: its semantic map
(`tracks.semantic_map.TrackMap`), tiles (`tracks.texture`) and collision bodies (`tracks.obstacles`) are
built from it.

The reference line runs along the centre of the ego lane (so s is the ego lane's own arc length); lanes
are indexed 0 = rightmost; lateral offsets t are + left. Lane widths are constant, or tabulated along s
(`width_table`), the lane lines then standing at the offsets of the nominal (median) widths.
"""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Sequence

import numpy as np

from tracks.geometry import ReferenceLine
from tracks.lane import Lane
from tracks.layout import Boundary, Edge, MarkingRun
from tracks.paint import AsphaltPainter, MarkingPainter
from tracks.pose import Pose
from tracks.profile import Profile
from tracks.tile_frame import Painter

SEDAN_WIDTH = 1.90  # m; the vehicle width the presets' lane straddle deviations are quoted for


class Track:
    """A named road (`name@seed`) with lanes, lane lines, edges, intersections and tiles."""

    def __init__(
        self,
        name: str,
        seed: int,
        description: str,
        reference: ReferenceLine,
        lane_widths: Sequence[float],
        line_kinds: Sequence[str],
        right: Edge,
        left: Edge,
        ego_lane: int = 0,
        intersections: Sequence[tuple[float, float]] = (),
        lidar_profile: tuple[np.ndarray, np.ndarray] | None = None,
        painters: Sequence[Painter] | None = None,
        tile_length: float = 20.0,
        px_per_m: float = 25.0,
        width_table: tuple[np.ndarray, np.ndarray] | None = None,
        oncoming: int = 0,
    ) -> None:
        if len(line_kinds) != len(lane_widths) + 1:
            raise ValueError("need one marking kind per lane line (lanes + 1)")
        if not 0 <= oncoming < len(lane_widths):
            raise ValueError(f"{oncoming} oncoming lanes on a road of {len(lane_widths)}: at least one lane must "
                             f"run along the reference line")
        if not 0 <= ego_lane < len(lane_widths) - oncoming:
            raise ValueError(f"ego lane {ego_lane} out of range (lanes along the road: "
                             f"0..{len(lane_widths) - oncoming - 1})")
        self.name = name
        self.seed = seed
        self.description = description
        self.reference = reference
        self.length = reference.length
        self.ego_lane = ego_lane
        self.right, self.left = right, left
        self.intersections = sorted((float(a), float(b)) for a, b in intersections)
        offsets = np.concatenate([[0.0], np.cumsum(lane_widths)])
        offsets -= offsets[ego_lane] + 0.5 * lane_widths[ego_lane]
        first_oncoming = len(lane_widths) - oncoming
        self.lanes = [
            Lane(reference, i, float(offsets[i] + 0.5 * w), float(w), profiles, -1 if i >= first_oncoming else 1)
            for i, (w, profiles) in enumerate(zip(lane_widths, self._profiles(width_table, len(lane_widths),
                                                                               ego_lane), strict=True))
        ]
        self.boundaries = [
            Boundary(float(t), self._runs(kind)) for t, kind in zip(offsets, line_kinds, strict=True)
        ]
        if lidar_profile is None:
            lidar_profile = (np.array([0.0, self.length]), np.ones(2))
        self._lidar_s, self._lidar_q = lidar_profile
        self.painters: list[Painter] = (
            list(painters) if painters is not None else [AsphaltPainter(), MarkingPainter()]
        )
        self.tile_length = tile_length
        self.px_per_m = px_per_m

    def __repr__(self) -> str:
        return f"Track({self.name}@{self.seed}, {self.length:.0f} m, {len(self.lanes)} lanes)"

    @staticmethod
    def _profiles(table: tuple[np.ndarray, np.ndarray] | None, n: int,
                  ego: int) -> list[tuple[Profile, Profile] | None]:
        """Per lane (centre offset, width) profiles from widths W[s, lane] at arc lengths s, the ego lane's
        centre on the reference line."""
        if table is None:
            return [None] * n
        s, widths = table
        if widths.shape != (len(s), n):
            raise ValueError(f"width table of shape {widths.shape}: need ({len(s)}, {n})")
        edges = np.concatenate([np.zeros((len(s), 1)), np.cumsum(widths, axis=1)], axis=1)
        centres = edges[:, :-1] + 0.5 * widths - (edges[:, ego] + 0.5 * widths[:, ego])[:, None]
        return [(Profile(s, centres[:, i]), Profile(s, widths[:, i])) for i in range(n)]

    def _runs(self, kind: str) -> tuple[MarkingRun, ...]:
        runs, s = [], 0.0
        for a, b in self.intersections:
            if a > s:
                runs.append(MarkingRun(s, a, kind))
            runs.append(MarkingRun(a, b, "none"))
            s = b
        if s < self.length:
            runs.append(MarkingRun(s, self.length, kind))
        return tuple(runs)

    # ---- cross section -----------------------------------------------------------------------
    @property
    def paved_range(self) -> tuple[float, float]:
        """Lateral extent [t_right, t_left] of the paved surface (lanes plus shoulders/gutters)."""
        return self.boundaries[0].t - self.right.paved, self.boundaries[-1].t + self.left.paved

    @property
    def lateral_range(self) -> tuple[float, float]:
        """Lateral extent [t_min, t_max] covered by the tiles (road plus roadside)."""
        return self.boundaries[0].t - self.right.extent, self.boundaries[-1].t + self.left.extent

    @property
    def oncoming(self) -> int:
        """Number of lanes (the leftmost) that run against the reference line."""
        return sum(ln.oncoming for ln in self.lanes)

    def in_intersection(self, s: float) -> bool:
        return any(a <= s < b for a, b in self.intersections)

    def lane_straddle_dev(self, lane: int | None = None, vehicle_width: float = SEDAN_WIDTH) -> float:
        """(lane width - vehicle width) / 2 for `lane` (default: the ego lane)."""
        return 0.5 * (self.lanes[self.ego_lane if lane is None else lane].width - vehicle_width)

    def start_pose(self, lane: int | None = None, s: float = 20.0) -> Pose:
        """Pose on the centre of `lane` (default: ego lane) at arc length s, heading along the road."""
        ln = self.lanes[self.ego_lane if lane is None else lane]
        x, y = ln.position(s, 0.0)
        return Pose(x, y, ln.heading_at(s))

    def road_surface_contains(self, x: float, y: float) -> bool:
        """True on the drivable paved surface: lanes, shoulders and the cross street in intersections."""
        s, t = self.reference.project(x, y)
        if not 0.0 <= s <= self.length:
            return False
        lo, hi = self.lateral_range if self.in_intersection(s) else self.paved_range
        return lo <= t <= hi

    @functools.cached_property
    def max_abs_curvature(self) -> float:
        """Largest |curvature| (1/m) of the reference line."""
        return float(np.max(np.abs(self.reference.curvature)))

    def surface_holds_disc(self, x: float, y: float, radius: float) -> bool:
        """True when every point within `radius` of (x, y) is surely on the paved surface: the centre projects
        `radius` inside the paved range and 2·radius inside the road's ends, where the curvature is mild
        enough at that offset (|k|·(|t| + radius) ≤ ½) that t changes no faster than the point moves and s
        at most twice as fast. False means: test the points themselves."""
        return self.band_holds_disc(x, y, radius, self.paved_range)

    def band_holds_disc(self, x: float, y: float, radius: float, band: tuple[float, float]) -> bool:
        """`surface_holds_disc` for the lateral band [lo, hi] (t, m) in place of the paved range: every point within
        `radius` of (x, y) surely has lo ≤ t ≤ hi and 0 ≤ s ≤ length."""
        s, t = self.reference.project(x, y)
        lo, hi = band
        return (self.max_abs_curvature * (abs(t) + radius) <= 0.5 and lo + radius <= t <= hi - radius
                and 2.0 * radius <= s <= self.length - 2.0 * radius)

    def edge_kind_at(self, x: float, y: float) -> str | None:
        """None on the paved surface; otherwise the kind of the edge the point lies beyond
        ('drop_off' there means the vehicle fell off the road). Beyond either road end: 'open'."""
        if self.road_surface_contains(x, y):
            return None
        s, t = self.reference.project(x, y)
        if not 0.0 <= s <= self.length:
            return "open"
        lo, hi = self.paved_range
        return self.left.kind if t > 0.5 * (lo + hi) else self.right.kind

    def lidar_feature_quality(self, s: float) -> float:
        """LiDAR map-matching feature richness at s: 1 rich, near 0 feature-poor (smooth, seeded)."""
        return float(np.interp(s, self._lidar_s, self._lidar_q))

    # ---- tiles -------------------------------------------------------------------------------
    @property
    def n_tiles(self) -> int:
        return math.ceil(self.length / self.tile_length - 1e-9)

    def tiles_near(self, x: float, y: float, radius: float) -> list[int]:
        """Indices of tiles with any part within about `radius` m (along the road) of (x, y)."""
        s, _ = self.reference.project(x, y)
        return self.tiles_along(s, radius, radius)

    def tiles_along(self, s: float, behind: float, ahead: float) -> list[int]:
        """Indices of tiles with any part from `behind` m before station s to `ahead` m after it."""
        first = max(0, math.floor((s - behind) / self.tile_length))
        last = min(self.n_tiles - 1, math.ceil((s + ahead) / self.tile_length) - 1)
        return list(range(first, last + 1))

    def with_painters(self, painters: Sequence[Painter]) -> Track:
        """A copy of this track whose tiles `painters` paint after its own (a condition's wear, an attack's
        patch); the track itself is left as it is."""
        painted = copy.copy(self)
        painted.painters = [*self.painters, *painters]
        return painted
