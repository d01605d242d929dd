"""The ego's car following against the IDM's braking term, and in closed loop behind a parked car."""

import pytest

from testbed.control.car_following import CarFollowing, LeadCar
from testbed.control.idm import IdmParams, desired_gap
from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import apply_settings, load_scenario

IDM = IdmParams(brake_limit=8.0)


def test_no_car_ahead_caps_nothing_and_a_far_one_hardly():
    following = CarFollowing(IDM)
    assert following.cap(20.0, None) is None
    assert following.cap(20.0, LeadCar(gap=500.0, speed=20.0)) == pytest.approx(IDM.accel, rel=0.02)


def test_the_cap_is_the_idm_braking_term_and_stops_at_the_brake_limit():
    following = CarFollowing(IDM)
    v, lead = 15.0, LeadCar(gap=30.0, speed=10.0)
    s_star = desired_gap(IDM, v, v - lead.speed)
    assert following.cap(v, lead) == pytest.approx(IDM.accel * (1.0 - (s_star / lead.gap) ** 2))
    assert following.cap(v, lead) < 0.0  # closing inside its desired gap: it brakes
    assert following.cap(27.0, LeadCar(gap=5.0, speed=0.0)) == -IDM.brake_limit
    assert following.cap(0.0, LeadCar(gap=IDM.min_gap, speed=0.0)) == pytest.approx(0.0)  # standing at s0


@pytest.mark.parametrize("follows", [False, True])
def test_the_ego_runs_into_a_parked_car_unless_it_follows_cars(follows):
    sc = apply_settings(load_scenario("parking-lot").with_overrides(duration=20.0), [
        "traffic.vehicles=1", "traffic.ahead=25", "traffic.speed=0", "traffic.speed_spread=0",
        f"traffic.ego_follows={str(follows).lower()}"])
    sim = SimRun(sc, render=False)
    try:
        summary = sim.run().summary
        gap = sim.parts.traffic.cars[0].s - sim.parts.smap.project(sim.loop.last_state.true_pose, sim.parts.lane).s \
            - 0.5 * (sim.parts.params.length + sim.parts.traffic.length)
    finally:
        sim.close()
    if follows:
        assert summary["hit_vehicle"] is None and summary["sim_time_s"] == pytest.approx(20.0)
        assert IDM.min_gap - 0.5 < gap < IDM.min_gap + 1.0 and sim.rows[-1].speed < 0.05  # stands behind it
    else:
        assert summary["consequence"] == "hit_vehicle" and summary["hit_vehicle"]["id"] == 0
