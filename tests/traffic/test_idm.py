"""The IDM against its equations: free road, the desired gap, equilibrium spacing, braking limit, integration."""

import math

import pytest

from testbed.control.idm import IdmParams, desired_gap, idm_accel, integrate

P = IdmParams(accel=1.5, decel=2.0, headway=1.5, min_gap=2.0, delta=4.0, brake_limit=9.0)


def test_free_road_is_a_times_one_minus_speed_ratio_to_the_delta() -> None:
    assert idm_accel(P, 0.0, 20.0) == pytest.approx(1.5)
    assert idm_accel(P, 10.0, 20.0) == pytest.approx(1.5 * (1 - 0.5 ** 4))
    assert idm_accel(P, 20.0, 20.0) == pytest.approx(0.0)
    assert idm_accel(P, 22.0, 20.0) < 0.0


def test_desired_gap_is_s0_plus_v_t_plus_the_closing_term() -> None:
    v, dv = 15.0, 3.0
    assert desired_gap(P, v, dv) == pytest.approx(2.0 + 15.0 * 1.5 + 15.0 * 3.0 / (2 * math.sqrt(1.5 * 2.0)))
    assert desired_gap(P, v, -100.0) == pytest.approx(2.0)  # an opening gap never asks for less than s0


def test_interaction_term_and_equilibrium_spacing() -> None:
    v, v0, gap, dv = 12.0, 20.0, 25.0, 1.0
    s_star = desired_gap(P, v, dv)
    assert idm_accel(P, v, v0, gap, dv) == pytest.approx(1.5 * (1 - (v / v0) ** 4 - (s_star / gap) ** 2))
    # equilibrium: s_e = s*(v, 0) / sqrt(1 - (v/v0)^delta) holds a steady speed behind an equal-speed leader
    s_e = desired_gap(P, v, 0.0) / math.sqrt(1 - (v / v0) ** 4)
    assert idm_accel(P, v, v0, s_e, 0.0) == pytest.approx(0.0, abs=1e-12)


def test_touching_or_overlapping_brakes_at_the_limit() -> None:
    assert idm_accel(P, 10.0, 20.0, 0.0, 10.0) == -9.0
    assert idm_accel(P, 10.0, 20.0, -3.0, 0.0) == -9.0


def test_integration_is_ballistic_and_stops_at_standstill() -> None:
    assert integrate(10.0, 1.0, 0.1) == pytest.approx((10.0 * 0.1 + 0.5 * 0.01, 10.1))
    ds, v = integrate(1.0, -9.0, 0.5)
    assert v == 0.0 and ds == pytest.approx(1.0 / 18.0)
    assert integrate(0.0, -2.0, 0.1) == (0.0, 0.0)
