"""The physics world's contact query skipped out of reach: every skipped query, made anyway, is empty (drives
that hit guardrails, curbs and a parked car), the skips happen on a free road, and the band clear of roadside
bodies holds none of their boxes."""

from __future__ import annotations

import math

import pytest

from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import load_scenario
from tracks.obstacles import clear_band, road_obstacles
from tracks.presets import load_track


def _attacked(direction: str) -> dict:
    return {"duration": 30.0, "localization": "msf", "defense": "none", "detector": "oracle",
            "attack": {"kind": "fusionripper", "direction": direction, "start": 5.0}}


PARKED_AHEAD = {"vehicles": 1, "lanes": [1], "speed": 0.0, "speed_spread": 0.0, "ahead": 40.0}


@pytest.mark.parametrize(("track", "overrides", "consequence", "least_skipped"), [
    ("highway", {"duration": 20.0, "speed": 27.0, "localization": "msf", "detector": "none"}, "reach_destination",
     0.99),
    ("highway", _attacked("right"), "hit_barrier", 0.5),
    ("highway", _attacked("left"), "hit_barrier", 0.5),
    ("urban-curvy", _attacked("left"), "hit_curb", 0.0),
    ("highway", {"duration": 12.0, "speed": 12.0, "localization": "truth", "detector": "none",
                 "traffic": PARKED_AHEAD}, "hit_vehicle", 0.3),
])
def test_every_skipped_contact_query_would_have_found_no_contact(track, overrides, consequence, least_skipped):
    sim = SimRun(load_scenario(track).replace(**overrides), render=False)
    world = sim.parts.world
    world.verify_skips = True  # a skipped query is made anyway and raises if it had contacts
    try:
        result = sim.run()
    finally:
        sim.close()
    assert result.summary["consequence"] == consequence
    assert world.skipped >= least_skipped * len(result.rows)
    assert world.skipped < len(result.rows)  # the contact itself was asked for


def test_a_skipped_query_that_had_contacts_raises(monkeypatch):
    sim = SimRun(load_scenario("highway").replace(**_attacked("right")), render=False)
    world = sim.parts.world
    world.verify_skips = True
    monkeypatch.setattr(world, "_band", (-math.inf, math.inf))  # a band that ignores the guardrails
    try:
        with pytest.raises(RuntimeError, match="skipped contact query"):
            sim.run()
    finally:
        sim.close()


@pytest.mark.parametrize("name", ["highway", "urban-curvy", "two-way", "local"])
def test_no_roadside_box_reaches_into_the_clear_band(name):
    track = load_track(name)
    lo, hi = clear_band(track)
    assert lo < 0.0 < hi
    for box in road_obstacles(track):
        (x, y, _), (hx, hy, _), yaw = box.center, box.half_extents, box.yaw
        c, s = math.cos(yaw), math.sin(yaw)
        for u in (-hx, hx):
            for v in (-hy, hy):
                t = track.reference.project(x + c * u - s * v, y + s * u + c * v)[1]
                assert not lo < t < hi, (name, box)
