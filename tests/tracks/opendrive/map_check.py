"""Largest differences between a track's map answers and the file's analytic lane geometry."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from tests.tracks.opendrive.analytic import closest, lane_centre, reference
from tracks.pose import Pose
from tracks.road import Track
from tracks.semantic_map import TrackMap


def map_errors(track: Track, root: ET.Element, legs: list[tuple[str, int]], step: float = 7.0) -> dict[str, float]:
    """Max |error| of lane_dev, lane_point (position, heading) and lane_width over every lane of every leg
    (road id, direction), at poses off each lane centre by −0.6, 0 and +0.5 m; the track's lanes along the route
    are the file's lanes of the driving direction, its oncoming lanes those of the other side, each posed and
    measured in its own direction of travel (where the road has them)."""
    roads = {r.get("id"): r for r in root.findall("road")}
    smap, n = TrackMap(track), len(track.lanes) - track.oncoming
    worst = dict.fromkeys(("dev", "point", "heading", "width"), 0.0)
    for road_id, direction in legs:
        road = roads[road_id]
        length = float(road.get("length"))
        for s in np.arange(1.0, length - 1.0, step):
            _, _, h = reference(road, s)
            for i in range(len(track.lanes)):
                way = direction if i < n else -direction
                lane_id = -direction * (n - i) if i < n else direction * (i - n + 1)
                if road.find(f".//lane[@id='{lane_id}']") is None:
                    continue  # a connecting road without the other direction's lanes
                travel = h if way == 1 else h + math.pi
                left = np.array([-math.sin(travel), math.cos(travel)])
                for delta in (-0.6, 0.0, 0.5):
                    xy = lane_centre(road, lane_id, s) + delta * left
                    _, centre, dev, width = closest(road, lane_id, xy, s)
                    pose = Pose(float(xy[0]), float(xy[1]), travel)
                    point, heading = smap.lane_point(pose, i)
                    ahead = lane_centre(road, lane_id, min(s + 0.01, length)) - lane_centre(road, lane_id, s)
                    want = math.atan2(ahead[1], ahead[0]) + (0.0 if way == 1 else math.pi)
                    worst["dev"] = max(worst["dev"], abs(smap.lane_dev(pose, i) - way * dev))
                    worst["point"] = max(worst["point"], float(np.hypot(*(point - centre))))
                    worst["heading"] = max(worst["heading"], abs(math.remainder(heading - want, 2 * math.pi)))
                    worst["width"] = max(worst["width"], abs(smap.lane_width(pose, i) - width))
    return worst
