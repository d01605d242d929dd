"""OpenDRIVE export of every preset: valid against the ASAM OpenDRIVE 1.7 schema, read by an independent
reader (pyxodr) onto the preset's own lanes, and imported again with the same map answers within 1 cm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scenariogeneration
import xmlschema
from pyxodr_omega_prime.road_objects.network import RoadNetwork

from tracks.opendrive.load import load_xodr
from tracks.opendrive.write import write_xodr
from tracks.pose import Pose
from tracks.presets import PRESETS, load_track
from tracks.road import Track
from tracks.semantic_map import TrackMap

SPECS = [*PRESETS, "local@3", "urban-curvy@7"]
SCHEMA = Path(scenariogeneration.__file__).parents[1] / "schemas" / "opendrive_17_core.xsd"


@pytest.fixture(scope="module")
def schema() -> xmlschema.XMLSchema:
    return xmlschema.XMLSchema(str(SCHEMA))


def _exported(spec: str, tmp_path: Path) -> tuple[Track, Path]:
    track = load_track(spec)
    path = tmp_path / f"{spec.replace('@', '-')}.xodr"
    write_xodr(track, path)
    return track, path


def map_differences(a: Track, b: Track, n: int = 400) -> dict[str, float]:
    """Max |difference| of lane_dev, lane_point, lane heading and lane_width between two tracks' maps at random
    poses within ±1.2 m of every lane centre of `a` (lanes matched by index)."""
    ma, mb = TrackMap(a), TrackMap(b)
    rng = np.random.default_rng(0)
    worst = dict.fromkeys(("dev", "point", "heading", "width"), 0.0)
    for s in rng.uniform(1.0, a.length - 1.0, n):
        for i, lane in enumerate(a.lanes):
            x, y = lane.position(s, rng.uniform(-1.2, 1.2))
            pose = Pose(x, y, 0.0)
            (pa, ha), (pb, hb) = ma.lane_point(pose, i), mb.lane_point(pose, i)
            worst["dev"] = max(worst["dev"], abs(ma.lane_dev(pose, i) - mb.lane_dev(pose, i)))
            worst["point"] = max(worst["point"], float(np.hypot(*(pa - pb))))
            worst["heading"] = max(worst["heading"], abs(float(np.remainder(ha - hb + np.pi, 2 * np.pi) - np.pi)))
            worst["width"] = max(worst["width"], abs(ma.lane_width(pose, i) - mb.lane_width(pose, i)))
    return worst


@pytest.mark.parametrize("spec", SPECS)
def test_export_then_import_gives_the_same_map_within_1_cm(spec, tmp_path, schema):
    track, path = _exported(spec, tmp_path)
    schema.validate(str(path))
    again = load_xodr(str(path))
    assert len(again.lanes) == len(track.lanes) and again.ego_lane == track.ego_lane
    assert [b.runs[0].kind for b in again.boundaries] == [b.runs[0].kind for b in track.boundaries]
    assert len(again.intersections) == len(track.intersections)
    assert again.length == pytest.approx(track.length, rel=0.01)
    worst = map_differences(track, again)
    assert max(worst["dev"], worst["point"], worst["width"]) < 0.01 and worst["heading"] < 1e-3, worst


@pytest.mark.parametrize("spec", ["urban-curvy", "highway", "local"])
def test_an_independent_reader_puts_the_exported_lanes_on_the_presets_lanes(spec, tmp_path):
    track, path = _exported(spec, tmp_path)
    worst, seen = 0.0, 0
    for road in RoadNetwork(str(path)).get_roads():
        for section in road.lane_sections:
            for lane in section.right_lanes:
                if lane.type != "driving":
                    continue
                for x, y in lane.centre_line[::5, :2]:
                    s, t = track.reference.project(x, y)
                    if 0.5 < s < track.length - 0.5:
                        worst, seen = max(worst, abs(t - track.lanes[len(track.lanes) + lane.id].offset)), seen + 1
    assert seen > 500 and worst < 0.01
