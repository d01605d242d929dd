"""The pose a run over CAN is judged on: chosen by what the link can see of the plant, and named in the summary;
a chassis whose steering sensor is off drives its plant into the curb while the odometry stays in lane."""

from __future__ import annotations

import math

import pytest

from hil.emulator.consequence_basis import consequence_basis
from hil.emulator.plants import scenario_plant
from hil.emulator.scenario_run import LinkConfig, run_hil_scenario
from hil.link.profile import load_profile
from testbed.eval.run.scenario import load_scenario
from testbed.presets import vehicle
from tracks.pose import Pose
from tracks.presets import CURB


def test_the_plant_in_this_process_then_an_emulator_s_truth_frames_then_odometry():
    sc = load_scenario("parking-lot")
    plant = scenario_plant(sc)
    truth = Pose(1.0, 2.0, 0.3)
    try:
        in_process = consequence_basis(plant, lambda: truth)
        assert in_process.name == "plant" and in_process.pose() == plant.read().true_pose != truth
    finally:
        plant.world.close()
    framed = consequence_basis(None, lambda: truth)
    assert framed.name == "plant" and framed.pose() == truth
    assert consequence_basis(None, None).name == "odometry" and consequence_basis(None, None).pose is None


def test_a_steering_offset_puts_the_plant_on_the_curb_and_the_summary_judges_both_on_the_plant(tmp_path):
    sc = load_scenario("urban-curvy").with_overrides(duration=30.0, speed=4.0, localization="msf", defense="ld3")
    sc = sc.replace(chassis={"steer_offset_deg": 0.5})
    summary = run_hil_scenario(sc, None, LinkConfig("virtual", truth=True)).summary
    # the curb's face lies CURB.gap beyond the lane's edge: a car's side reaches it from |D| = straddle + gap, less
    # what a corner swings out at the plant's heading error (half the car's length × sin 0.15 rad at most here)
    params = vehicle(sc.vehicle)
    reach = summary["lane_straddle_dev_m"] + CURB.gap - 0.5 * params.length * math.sin(0.15)
    assert summary["consequence"] == "hit_curb" and summary["max_abs_dev_m"] > reach > 0.3
    assert summary["final_dev_m"] < 0.0 and summary["consequence_basis"] == "plant"  # the curb is on the right
    # the odometry, fed the offset steering, believed the car centred: its own figures say so, named as its own
    assert abs(summary["odometry_max_abs_dev_m"]) < 0.1 and summary["odometry_error_max_m"] > reach


@pytest.mark.parametrize(("interface", "truth", "basis"), [("slcan", True, "plant"), ("slcan", False, "odometry")])
def test_an_ecu_process_is_judged_on_its_truth_frames_where_it_sends_them(interface, truth, basis):
    assert load_profile("ld3-dev").simulation.truth  # the default profile sends them unless told not to
    sc = load_scenario("parking-lot").with_overrides(duration=1.0, seed=3)
    summary = run_hil_scenario(sc, None, LinkConfig(interface, truth=truth)).summary
    assert summary["consequence_basis"] == basis and summary["consequence"] == "reach_destination"
    if basis == "odometry":
        assert summary["max_abs_dev_m"] == summary["odometry_max_abs_dev_m"]
    else:
        assert summary["max_abs_dev_m"] == pytest.approx(summary["odometry_max_abs_dev_m"], abs=0.05)
