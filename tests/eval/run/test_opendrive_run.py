"""Benign lane keeping at 15 m/s on a route of OpenDRIVE roads through a junction, the file written by an
independent OpenDRIVE writer (scenariogeneration): the car keeps its lane to the end of the route."""

from __future__ import annotations

import json

from scenariogeneration import xodr

from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import load_scenario


def write_route(path) -> None:
    """Road 1 (120 m line) → road 2 (clothoid, R 200 m arc, clothoid) → junction 100 (connecting road 10, a
    right S of clothoids) → road 3 (120 m line); two lanes each way outside the junction."""
    k, s = 1 / 200, -1 / 250
    r1 = xodr.create_road(xodr.Line(120), 1, left_lanes=2, right_lanes=2, lane_width=3.5)
    r2 = xodr.create_road([xodr.Spiral(0.0, k, 40), xodr.Arc(k, 60), xodr.Spiral(k, 0.0, 40)], 2, left_lanes=2,
                          right_lanes=2, lane_width=3.5)
    c = xodr.create_road([xodr.Spiral(0.0, s, 30), xodr.Spiral(s, 0.0, 30)], 10, left_lanes=0, right_lanes=2,
                         lane_width=3.5, road_type=100)
    r3 = xodr.create_road(xodr.Line(120), 3, left_lanes=2, right_lanes=2, lane_width=3.5)
    r1.add_successor(xodr.ElementType.road, 2, xodr.ContactPoint.start)
    r2.add_predecessor(xodr.ElementType.road, 1, xodr.ContactPoint.end)
    r2.add_successor(xodr.ElementType.junction, 100)
    c.add_predecessor(xodr.ElementType.road, 2, xodr.ContactPoint.end)
    c.add_successor(xodr.ElementType.road, 3, xodr.ContactPoint.start)
    r3.add_predecessor(xodr.ElementType.junction, 100)
    odr = xodr.OpenDrive("route")
    for road in (r1, r2, c, r3):
        odr.add_road(road)
    odr.add_junction(xodr.create_junction([c], 100, [r2, r3]))
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(path))


def test_benign_lane_keeping_at_15_m_s_on_an_imported_junction_route(tmp_path):
    path = tmp_path / "route.xodr"
    write_route(path)
    sc = load_scenario("urban-straight").with_overrides(track=f"xodr:{path}#1,2,10,3", speed=15.0, duration=45.0)
    run_scenario(sc, tmp_path / "run")
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["consequence"] == "reach_destination"
    assert summary["max_abs_dev_m"] <= 0.10
    assert summary["sim_time_s"] < 45.0, "the run ends at the end of the route, not at the duration"
