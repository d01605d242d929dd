"""Closed loops with traffic: a benign drive behind and beside cars, the ego driven into a parked car
(`hit_vehicle`), same seed same bytes, and a traffic table the track cannot hold."""

import csv
import json

import numpy as np
import pytest
from mcap.reader import make_reader

from testbed.eval.run.runner import SimRun, run_scenario
from testbed.eval.run.scenario import ScenarioError, load_scenario


def _highway(**overrides):
    return load_scenario("highway").replace(**{"localization": "truth", "detector": "none", **overrides})


def test_the_ego_drives_behind_and_beside_traffic_without_touching_it(tmp_path):
    sc = _highway(speed=15.0, duration=8.0, traffic={"vehicles": 5, "speed": 16.0, "speed_spread": 0.0, "ahead": 8.0})
    run_scenario(sc, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["consequence"] == "reach_destination" and summary["hit_vehicle"] is None
    assert summary["traffic_vehicles"] == 5
    with (tmp_path / "traffic.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 5 * 80 and {r["id"] for r in rows} == {str(i) for i in range(5)}
    with (tmp_path / "trajectory.csv").open() as fh:
        ego = {r["t"]: float(r["x"]) for r in csv.DictReader(fh)}
    lead = [r for r in rows if r["id"] == "1"]  # car 1 is the first in the ego lane (round-robin over 0, 1, 2)
    assert lead[0]["lane"] == "1"
    gaps = [float(r["x"]) - ego[r["t"]] for r in lead]  # the highway runs east for its first few hundred metres
    assert min(gaps) > 4.8
    front = [r for r in rows if r["id"] == "4"]  # the car ahead of it, free road: holds its desired speed
    assert float(front[-1]["speed"]) == pytest.approx(16.0, abs=0.05)
    assert 13.0 < float(lead[-1]["speed"]) < 16.0  # IDM: behind a car 40 m ahead, a little below v0


def test_the_ego_driven_into_a_parked_car_ends_hit_vehicle(tmp_path):
    sc = _highway(speed=12.0, duration=12.0,
                  traffic={"vehicles": 1, "lanes": [1], "speed": 0.0, "speed_spread": 0.0, "ahead": 40.0})
    result = run_scenario(sc, tmp_path)
    hit = result.summary["hit_vehicle"]
    assert result.summary["consequence"] == "hit_vehicle"
    assert hit["id"] == 0 and hit["lane"] == 1 and 6.0 < hit["relative_speed_mps"] < 13.0
    assert result.summary["sim_time_s"] < 12.0
    assert json.loads((tmp_path / "summary.json").read_text())["hit_vehicle"] == hit


def test_same_seed_gives_the_same_bytes_with_traffic(tmp_path):
    sc = _highway(speed=20.0, duration=3.0, localization="msf", traffic={"vehicles": 6, "beside": -10.0})
    outs = []
    for k, seed in enumerate((7, 7, 8)):
        run_scenario(sc.replace(seed=seed), tmp_path / f"r{k}")
        outs.append([(tmp_path / f"r{k}" / name).read_bytes() for name in ("trajectory.csv", "traffic.csv")])
    assert outs[0] == outs[1]
    assert outs[0][1] != outs[2][1]


def test_cars_started_at_rest_start_with_the_ego_and_give_the_same_bytes(tmp_path):
    sc = _highway(speed=20.0, duration=3.0, localization="msf", seed=7)
    outs = []
    for k, start in enumerate(({}, {"start_speed": 0.0}, {"start_speed": 0.0})):
        run_scenario(sc.replace(traffic={"vehicles": 6, "beside": -10.0, **start}), tmp_path / f"r{k}")
        outs.append((tmp_path / f"r{k}" / "traffic.csv").read_bytes())
    assert outs[1] == outs[2] and outs[0] != outs[1]
    with (tmp_path / "r1" / "traffic.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    first_t = rows[0]["t"]
    assert all(float(r["speed"]) < 0.1 for r in rows if r["t"] == first_t)
    assert all(float(r["speed"]) > 1.0 for r in rows[-6:])


def test_a_traffic_lane_the_track_lacks_is_refused_when_built():
    with pytest.raises(ScenarioError, match=r"^traffic\.lanes names lane 4, which highway lacks \(lanes 0\.\.2\)$"):
        SimRun(_highway(traffic={"vehicles": 2, "lanes": [4]}))


def test_the_camera_sees_a_car_ahead_and_it_hides_the_road_behind_it():
    sc = _highway(duration=2.0)
    frames = []
    for traffic in ({}, {"vehicles": 1, "lanes": [1], "speed": 0.0, "speed_spread": 0.0, "ahead": 10.0}):
        sim = SimRun(sc.replace(traffic=traffic), render=True)
        try:
            sim.parts.streamer.update(sim.parts.start)
            frames.append(sim.parts.camera.render(sim.parts.start).astype(int))
        finally:
            sim.close()
    changed = np.abs(frames[0] - frames[1]).sum(axis=2) > 30
    rows, cols = np.nonzero(changed)
    width = frames[0].shape[1]
    assert changed.mean() > 0.01 and abs(cols.mean() - width / 2) < 0.1 * width  # a box straight ahead
    red, green, blue = frames[1][rows, cols].mean(axis=0)
    assert red > 2 * green and red > 2 * blue  # car 0's colour


def test_the_recording_carries_the_traffic_poses_at_the_csv_rate(tmp_path):
    sc = _highway(duration=1.0, traffic={"vehicles": 3})
    run_scenario(sc, tmp_path, record=True)
    with (tmp_path / "run.mcap").open("rb") as f:
        messages = [json.loads(m.data) for _, channel, m in make_reader(f).iter_messages()
                    if channel.topic == "/traffic/poses"]
    with (tmp_path / "traffic.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(messages) == 10 and all(len(m["poses"]) == 3 for m in messages)
    assert messages[-1]["poses"][2]["position"]["x"] == pytest.approx(float(rows[-1]["x"]), abs=1e-3)


PARKED_LEFT = {"vehicles": 25, "lanes": [1], "speed": 0.0, "speed_spread": 0.0, "beside": 15.0, "gap": 6.0}
"""A row of parked cars in the lane left of urban-straight's ego lane."""


@pytest.mark.parametrize(("defense", "consequence"), [("none", "hit_vehicle"), ("ld3", "stop_in_lane")])
def test_fusionripper_pushes_the_car_into_parked_cars_unless_ld3_stops_it_in_lane(defense, consequence):
    sc = load_scenario("urban-straight").replace(
        duration=30.0, localization="msf", defense=defense, traffic=PARKED_LEFT,
        attack={"kind": "fusionripper", "direction": "right", "start": 5.0})  # spoofed right: the car goes left
    summary = run_scenario(sc, None).summary
    assert summary["consequence"] == consequence
    if defense == "none":
        assert summary["hit_vehicle"]["lane"] == 1 and summary["hit_vehicle"]["relative_speed_mps"] > 5.0
    else:
        assert summary["hit_vehicle"] is None and summary["detected"]


def _two_way(**overrides):
    return load_scenario("two-way").replace(**{"localization": "truth", "detector": "none", **overrides})


def test_oncoming_cars_pass_the_ego_on_a_two_way_road_and_a_benign_drive_stays_in_lane(tmp_path):
    sc = _two_way(duration=10.0, traffic={"vehicles": 3, "lanes": [1], "speed_spread": 0.0, "ahead": 20.0})
    summary = run_scenario(sc, tmp_path).summary
    assert summary["consequence"] == "reach_destination" and summary["hit_vehicle"] is None
    with (tmp_path / "traffic.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    with (tmp_path / "trajectory.csv").open() as fh:
        ego = {r["t"]: float(r["x"]) for r in csv.DictReader(fh)}
    first = [r for r in rows if r["id"] == "0"]
    assert all(r["lane"] == "1" and abs(abs(float(r["yaw"])) - np.pi) < 0.3 for r in first[:20])
    ahead = [float(r["x"]) - ego[r["t"]] for r in first[:40]]  # the road runs east for its first 150 m
    assert ahead[0] > 20.0 and min(ahead) < -20.0  # it came at the ego and passed it


@pytest.mark.parametrize(("defense", "consequence"), [("none", "hit_vehicle"), ("ld3", "stop_in_lane")])
def test_fusionripper_steers_the_car_into_oncoming_traffic_unless_ld3_stops_it_in_lane(defense, consequence):
    sc = load_scenario("two-way").replace(
        duration=30.0, localization="msf", defense=defense, seed=1,
        traffic={"vehicles": 6, "lanes": [1], "gap": 25.0, "speed_spread": 0.0},
        attack={"kind": "fusionripper", "direction": "right", "start": 5.0})  # spoofed right: the car goes left
    summary = run_scenario(sc, None).summary
    assert summary["consequence"] == consequence
    if defense == "none":
        hit = summary["hit_vehicle"]
        assert hit["lane"] == 1 and hit["relative_speed_mps"] > 10.0  # the oncoming car brakes, the ego does not
    else:
        assert summary["hit_vehicle"] is None and summary["detected"]


def test_same_seed_gives_the_same_bytes_with_oncoming_traffic(tmp_path):
    sc = _two_way(duration=6.0, localization="msf", traffic={"vehicles": 6, "gap": 15.0})
    outs = []
    for k, seed in enumerate((3, 3, 4)):
        run_scenario(sc.replace(seed=seed), tmp_path / f"r{k}")
        outs.append([(tmp_path / f"r{k}" / name).read_bytes() for name in ("trajectory.csv", "traffic.csv")])
    assert outs[0] == outs[1]
    assert outs[0][1] != outs[2][1]
