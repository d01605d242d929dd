"""Closed loop on a dynamic-bicycle plant (0.5 rad/s steer-rate limit, 0.1 s actuator lags, 100 Hz,
2 cm / 0.002 rad pose noise): the lane-keeping, speed and in-lane stop targets, with margin."""

from __future__ import annotations

import numpy as np
import pytest

from testbed.control.planner import AR_DECEL, LanePlanner
from tests.control.closed_loop import drive
from tests.control.lane_map import curvy_urban, highway, straight
from tests.control.plant import BicyclePlant, PlantParams

# the controller assumes 141 kN/rad per axle and the CG at mid-wheelbase; the plants differ
TYRES = {
    "nominal": PlantParams(),
    "near-kinematic": PlantParams(cf=5e5, cr=5e5),
    "soft": PlantParams(cf=0.8e5, cr=1.0e5),
}


@pytest.mark.parametrize("speed", [10.0, 12.0, 27.0])
def test_straight_road_keeps_the_centreline(speed: float) -> None:
    trace = drive(straight(), speed, 8.0, np.random.default_rng(1)).arrays()
    assert np.abs(trace["dev"]).max() < 0.05  # target 0.10 m
    assert np.abs(trace["speed"] - speed).max() < 0.3


@pytest.mark.parametrize("speed", [10.0, 27.0])
def test_initial_offset_converges_without_large_overshoot(speed: float) -> None:
    trace = drive(straight(), speed, 8.0, np.random.default_rng(2), offset=0.3).arrays()
    settled = trace["t"] >= 3.0
    assert np.abs(trace["dev"][settled]).max() < 0.05
    assert trace["dev"].min() > -0.1


@pytest.mark.parametrize("tyres", TYRES)
def test_curvy_urban_road_at_10_mps(tyres: str) -> None:
    trace = drive(curvy_urban(), 10.0, 26.0, np.random.default_rng(3), plant_params=TYRES[tyres]).arrays()
    assert np.abs(trace["dev"]).max() < 0.15  # target 0.25 m (R = 60 m, clothoid transitions)


@pytest.mark.parametrize("tyres", TYRES)
def test_highway_at_27_mps(tyres: str) -> None:
    trace = drive(highway(), 27.0, 23.0, np.random.default_rng(4), plant_params=TYRES[tyres]).arrays()
    assert np.abs(trace["dev"]).max() < 0.10  # target 0.15 m (R = 600 m)
    assert np.abs(trace["speed"] - 27.0).max() < 0.3


def test_without_a_gyro_the_estimated_yaw_rate_suffices() -> None:
    trace = drive(curvy_urban(), 10.0, 26.0, np.random.default_rng(5), gyro=False).arrays()
    assert np.abs(trace["dev"]).max() < 0.15


def test_start_from_standstill_reaches_cruise_speed() -> None:
    trace = drive(straight(), 12.0, 20.0, np.random.default_rng(6), offset=0.2, start_speed=0.0).arrays()
    late = trace["t"] >= 15.0  # the 1 m/s² ramp ends at 12 s
    assert np.abs(trace["speed"][late] - 12.0).max() < 0.3
    assert np.abs(trace["dev"][late]).max() < 0.05


def test_in_lane_stop_from_27_mps_at_4_mps2() -> None:
    t_stop = 2.0

    def stop(t: float, planner: LanePlanner, plant: BicyclePlant) -> None:
        if abs(t - t_stop) < 1e-9:
            planner.start_stop(t, plant.vx, AR_DECEL)

    trace = drive(highway(), 27.0, 12.0, np.random.default_rng(7), on_tick=stop).arrays()
    t, v = trace["t"], trace["speed"]
    i0, i1 = np.argmax(v < 24.0), np.argmax(v < 3.0)
    mean_decel = (v[i0] - v[i1]) / (t[i1] - t[i0])
    assert mean_decel == pytest.approx(AR_DECEL, abs=0.3)
    assert t[np.argmax(v == 0.0)] < t_stop + 27.0 / AR_DECEL + 0.5
    assert (v[t > t_stop + 27.0 / AR_DECEL + 0.5] == 0.0).all()  # stays stopped (brake hold)
    assert np.abs(trace["dev"]).max() < 0.1
    assert abs(trace["dev"][-1]) < 0.1  # target 0.3 m
