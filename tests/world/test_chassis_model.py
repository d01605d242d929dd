"""`[chassis]`: a simulated chassis that reports no yaw rate of its own (ψ̇ = v tan δ / L from its steering angle,
as a CAN chassis without a yaw-rate report is read) and a miscalibrated steering sensor. The simulated IMU keeps
measuring the body; closed loop on a 1° offset LD3 keeps the car in its lane only with odometry's bias learnt."""

from __future__ import annotations

import dataclasses
import math

import pytest

from testbed import api
from testbed.chassis import ChassisCommand, ChassisModel, ChassisState, bicycle_yaw_rate
from testbed.direct_chassis import DirectChassis
from testbed.eval.run.scenario import ScenarioError, apply_settings, load_scenario
from testbed.eval.run.scenario_toml import scenario_document
from testbed.presets import build_track, vehicle
from testbed.world import PhysicsWorld


def test_the_table_is_set_written_and_refused_like_the_others():
    sc = apply_settings(load_scenario("parking-lot"), ["chassis.yaw_rate=\"steering\"", "chassis.steer_offset_deg=0.5"])
    assert sc.chassis == ChassisModel(yaw_rate="steering", steer_offset_deg=0.5)
    assert scenario_document(sc)["chassis"] == {"yaw_rate": "steering", "steer_offset_deg": 0.5}
    assert "chassis" not in scenario_document(load_scenario("parking-lot"))
    with pytest.raises(ScenarioError, match="steer_offset_deg"):
        apply_settings(sc, ["chassis.steer_offset_deg=20"])
    with pytest.raises(ScenarioError, match="yaw_rate"):
        apply_settings(sc, ["chassis.yaw_rate=\"gyro\""])


def turning_chassis(model: ChassisModel) -> DirectChassis:
    """The sedan on parking-lot after 2 s at 0.1 rad of steering command and a gentle throttle."""
    track, params = build_track("parking-lot"), vehicle("sedan")
    chassis = DirectChassis(PhysicsWorld(track, params, track.start_pose(track.ego_lane, 20.0)), model=model)
    for _ in range(80):
        chassis.send(ChassisCommand(0.1, 1.0))
        chassis.advance(0.025)
    return chassis


def test_the_offset_sensor_reads_more_than_the_wheels_and_the_derived_yaw_rate_follows_it():
    offset = math.radians(1.0)
    plain, derived = turning_chassis(ChassisModel()), turning_chassis(ChassisModel(yaw_rate="steering",
                                                                                  steer_offset_deg=1.0))
    try:
        a, b = plain.read(), derived.read()
        assert a.true_yaw_rate is None and a.body_yaw_rate == a.yaw_rate
        assert b.steer == pytest.approx(0.1, abs=2e-3)  # the servo closes its loop on the offset sensor
        assert derived.vehicle.steer_angle() == pytest.approx(0.1 - offset, abs=2e-3)  # the wheels: 1° short
        assert b.yaw_rate == bicycle_yaw_rate(b.speed, b.steer, derived.vehicle.params.wheelbase)
        assert b.body_yaw_rate == b.true_yaw_rate and b.true_yaw_rate < b.yaw_rate - 0.5 * b.speed * offset / 2.8
    finally:
        plain.world.close()
        derived.world.close()


def driven_states(steer_sensor: bool) -> list[ChassisState]:
    """The sedan on parking-lot steered left, then right, throttled, then braked: its state read every tick, by a
    chassis with or without the steering sensor."""
    track, params = build_track("parking-lot"), vehicle("sedan")
    chassis = DirectChassis(PhysicsWorld(track, params, track.start_pose(track.ego_lane, 20.0)),
                            steer_sensor=steer_sensor)
    try:
        states = [chassis.read()]
        for k in range(120):
            chassis.send(ChassisCommand(0.1 if k < 60 else -0.05, 1.0 if k < 90 else -3.0))
            chassis.advance(0.025)
            states.append(chassis.read())
        return states
    finally:
        chassis.world.close()


def test_a_chassis_without_the_steering_sensor_reports_nan_and_drives_to_the_same_bits():
    sensed, unsensed = driven_states(True), driven_states(False)
    assert all(math.isnan(s.steer) for s in unsensed) and sensed[-1].steer == pytest.approx(-0.05, abs=5e-3)
    assert [dataclasses.replace(s, steer=0.0) for s in sensed] == [dataclasses.replace(s, steer=0.0) for s in unsensed]
    track, params = build_track("parking-lot"), vehicle("sedan")
    world = PhysicsWorld(track, params, track.start_pose(track.ego_lane, 20.0))
    try:
        with pytest.raises(ValueError, match="steering sensor"):
            DirectChassis(world, model=ChassisModel(yaw_rate="steering"), steer_sensor=False)
    finally:
        world.close()


def test_a_chassis_state_without_a_true_yaw_rate_gives_the_imu_the_reported_one():
    assert ChassisState(0.0, 5.0, 0.0, 0.0, yaw_rate=0.2).body_yaw_rate == 0.2
    assert ChassisState(0.0, 5.0, 0.0, 0.0, yaw_rate=0.2, true_yaw_rate=0.1).body_yaw_rate == 0.1


@pytest.mark.parametrize("offset", [1.0, -1.0])
def test_a_steering_offset_with_a_derived_yaw_rate_keeps_the_lane_only_with_odometry_s_bias_learnt(offset):
    sc = api.scenario("urban-curvy", duration=20.0, speed=4.0, localization="msf", defense="ld3", seed=3,
                      chassis={"yaw_rate": "steering", "steer_offset_deg": offset})
    learnt = api.run(sc).summary
    assert learnt["consequence"] == "reach_destination" and not learnt["detected"]
    assert learnt["max_abs_dev_m"] < 0.3
    wheelbase = vehicle("sedan").wheelbase
    assert learnt["odometry_bias_rad_per_m"] == pytest.approx(math.tan(math.radians(offset)) / wheelbase, rel=0.05)
    unlearnt = api.run(sc.replace(defense_params={"odometry_bias_span": 0.0})).summary
    assert unlearnt["consequence"] in ("hit_curb", "hit_lane_divider", "out_of_lane") and not unlearnt["detected"]
    assert unlearnt["odometry_bias_rad_per_m"] is None


def test_the_body_yaw_rate_is_also_reported_as_its_mean_over_the_period():
    plain, derived = turning_chassis(ChassisModel()), turning_chassis(ChassisModel(yaw_rate="steering"))
    try:
        before = plain.read()
        plain.send(ChassisCommand(-0.1, 1.0))  # the steering swings: the period's mean is not its end's sample
        plain.advance(0.025)
        after = plain.read()
        turned = math.remainder(after.true_pose.yaw - before.true_pose.yaw, math.tau)
        assert after.mean_yaw_rate == pytest.approx(turned / 0.025, rel=1e-12)
        assert after.odometry_yaw_rate == after.mean_yaw_rate != after.yaw_rate
        assert derived.read().mean_yaw_rate is None  # a chassis that derives its yaw rate measures no mean
        assert derived.read().odometry_yaw_rate == derived.read().yaw_rate
    finally:
        plain.world.close()
        derived.world.close()
