"""End to end: a parking-lot scenario over the CAN link (in-process ECU on a virtual bus, ECU process over
SLCAN on a pty) against the direct run with the same 50 Hz command hold."""

import json
import math

import can
import pytest

from hil.emulator.plants import plant_args_for, pybullet_plant, scenario_plant
from hil.emulator.scenario_run import LinkConfig, run_hil_scenario
from testbed.errors import UserError
from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import load_scenario
from testbed.rates import PHYSICS_HZ

TOLERANCE_M = 0.05


def short_parking_lot(seconds: float = 3.0):
    sc = load_scenario("parking-lot").with_overrides(duration=seconds, seed=3)
    return sc.replace(rates={"command_hold_s": 0.02})


def direct_rows(sc):
    sim = SimRun(sc)
    try:
        return sim.run().rows
    finally:
        sim.close()


def max_gap(a, b) -> float:
    assert len(a) == len(b)
    return max(math.hypot(p.x - q.x, p.y - q.y) for p, q in zip(a, b, strict=True))


def test_virtual_bus_run_matches_the_direct_run_and_writes_the_outputs(tmp_path):
    sc = short_parking_lot()
    result = run_hil_scenario(sc, tmp_path, LinkConfig("virtual"))
    direct = direct_rows(sc)
    assert direct[-1].x - direct[0].x > 3.0  # it drove off
    assert max_gap(result.rows, direct) < TOLERANCE_M
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["interface"] == "virtual" and summary["clock"] == "lockstep"
    assert summary["can_frames_rejected"] == 0 and summary["consequence"] == "reach_destination"
    assert (tmp_path / "trajectory.csv").is_file() and (tmp_path / "birdseye.png").is_file()
    assert summary["can_log"] == "can.asc"  # inside the run folder, named relative to it (it may be renamed)
    with can.LogReader(str(tmp_path / summary["can_log"])) as reader:
        logged = sum(1 for _ in reader)
    assert logged == summary["can_frames_logged"] == summary["can_frames_tx"] + summary["can_frames_rx"]
    assert summary["can_frames_tx"] >= 4 * len(result.rows) // 2  # a command cycle (3) + step per 20 ms at least


def test_slcan_pty_run_with_the_ecu_in_its_own_process_matches_the_direct_run():
    sc = short_parking_lot()
    result = run_hil_scenario(sc, None, LinkConfig("slcan"))
    assert result.summary["channel"].startswith("/dev/")
    assert result.summary["can_frames_rejected"] == 0
    assert max_gap(result.rows, direct_rows(sc)) < TOLERANCE_M


def test_blf_log_is_written_where_asked(tmp_path):
    sc = short_parking_lot(0.5)
    result = run_hil_scenario(sc, tmp_path / "out", log_path=tmp_path / "frames.blf")
    with can.LogReader(str(tmp_path / "frames.blf")) as reader:
        ids = {frame.arbitration_id for frame in reader}
    assert {0x130, 0x131, 0x132, 0x530, 0x540, 0x5F0, 0x5F1} <= ids
    assert result.summary["can_log"] == str(tmp_path / "frames.blf")


def test_ecu_process_plant_arguments_rebuild_the_scenario_plant():
    sc = load_scenario("parking-lot").with_overrides(lane=0)
    here, there = scenario_plant(sc), pybullet_plant(**plant_args_for(sc))
    try:
        assert here.read().true_pose == pytest.approx(there.read().true_pose)
        assert there.world.dt == here.world.dt == pytest.approx(1 / PHYSICS_HZ)
    finally:
        here.world.close()
        there.world.close()


def test_the_emulated_chassis_carries_the_scenario_s_steering_offset_into_an_ecu_process():
    sc = load_scenario("parking-lot").replace(chassis={"steer_offset_deg": 1.0})
    args = plant_args_for(sc)
    assert args["steer_offset_deg"] == "1.0" and "steer_offset_deg" not in plant_args_for(load_scenario("parking-lot"))
    here, there = scenario_plant(sc), pybullet_plant(**args)
    try:
        assert here.steer_offset == there.steer_offset == pytest.approx(math.radians(1.0))
        assert here.wheelbase is None  # over CAN the profile, not [chassis], says what is reported
    finally:
        here.world.close()
        there.world.close()


def test_chassis_settings_a_run_over_can_cannot_honour_are_refused():
    sc = load_scenario("parking-lot")
    with pytest.raises(UserError, match="profile says where the yaw rate comes from"):
        run_hil_scenario(sc.replace(chassis={"yaw_rate": "steering"}), None, LinkConfig("virtual"))
    with pytest.raises(UserError, match="miscalibrates the emulated chassis"):
        run_hil_scenario(sc.replace(chassis={"steer_offset_deg": 1.0}), None, LinkConfig("socketcan", "can0"))


def test_link_config_rejects_unknown_interfaces_and_socketcan_without_a_channel():
    with pytest.raises(ValueError, match="unknown CAN interface"):
        LinkConfig("no-such-interface")
    with pytest.raises(ValueError, match="socketcan needs --channel"):
        LinkConfig("socketcan")
    assert LinkConfig("socketcan", "can0").clock_mode.value == "realtime"


def pix_parking_lot(seconds: float):
    sc = load_scenario("parking-lot").with_overrides(duration=seconds, seed=3, speed=4.0)
    return sc.replace(rates={"command_hold_s": 0.02})


def test_pix_hooke_runs_over_virtual_and_slcan_stay_within_5_cm_of_the_direct_run(tmp_path):
    sc = pix_parking_lot(3.0)
    direct = direct_rows(sc)
    virtual = run_hil_scenario(sc, tmp_path, LinkConfig("virtual", profile="pix-hooke"))
    slcan = run_hil_scenario(sc, None, LinkConfig("slcan", profile="pix-hooke"))
    assert direct[-1].x - direct[0].x > 3.0
    for result in (virtual, slcan):
        assert result.summary["profile"] == "pix-hooke" and result.summary["can_frames_rejected"] == 0
        assert max_gap(result.rows, direct) < TOLERANCE_M
    with can.LogReader(str(tmp_path / "can.asc")) as reader:
        ids = {frame.arbitration_id for frame in reader}
    assert {0x130, 0x131, 0x132, 0x530, 0x532, 0x534} <= ids
    assert not ids & {0x540, 0x541, 0x5F2, 0x5F3}  # no truth frames on a pix-hooke bus by default
    assert virtual.summary["odometry_error_max_m"] is None and virtual.summary["pose_source"] == "odometry"


def test_truth_frames_on_request_measure_the_odometry_against_the_plant():
    result = run_hil_scenario(pix_parking_lot(3.0), None, LinkConfig("virtual", profile="pix-hooke", truth=True))
    assert 0.0 < result.summary["odometry_error_max_m"] < TOLERANCE_M


@pytest.mark.slow
@pytest.mark.parametrize("interface", ["virtual", "slcan"])
def test_pix_hooke_20_s_parking_lot_stays_within_5_cm_of_the_direct_run(interface):
    sc = pix_parking_lot(20.0)
    result = run_hil_scenario(sc, None, LinkConfig(interface, profile="pix-hooke"))
    direct = direct_rows(sc)
    n = min(len(result.rows), len(direct))
    assert result.rows[n - 1].t > 10.0 and abs(len(result.rows) - len(direct)) <= 1  # the road's end: both ~13 s
    assert max_gap(result.rows[:n], direct[:n]) < TOLERANCE_M


def test_ld3_dev_secoc_run_over_the_virtual_bus_stays_within_5_cm_of_the_ld3_dev_run():
    sc = short_parking_lot()
    plain = run_hil_scenario(sc, None, LinkConfig("virtual"))
    secured = run_hil_scenario(sc, None, LinkConfig("virtual", profile="ld3-dev-secoc"))
    assert plain.rows[-1].x - plain.rows[0].x > 3.0  # it drove off
    assert secured.summary["profile"] == "ld3-dev-secoc" and secured.summary["can_frames_rejected"] == 0
    assert secured.summary["consequence"] == plain.summary["consequence"] == "reach_destination"
    assert max_gap(secured.rows, plain.rows) < TOLERANCE_M


def test_ld3_dev_secoc_over_slcan_with_the_ecu_in_its_own_process():
    sc = short_parking_lot(1.5)
    result = run_hil_scenario(sc, None, LinkConfig("slcan", profile="ld3-dev-secoc"))
    assert result.summary["channel"].startswith("/dev/") and result.summary["can_frames_rejected"] == 0
    assert result.rows[-1].x - result.rows[0].x > 1.0 and not result.summary["faults"]


@pytest.mark.slow
@pytest.mark.parametrize("interface", ["virtual", "slcan"])
def test_ld3_dev_secoc_20_s_parking_lot_stays_within_5_cm_of_the_ld3_dev_run(interface):
    sc = short_parking_lot(20.0)
    plain = run_hil_scenario(sc, None, LinkConfig("virtual"))
    secured = run_hil_scenario(sc, None, LinkConfig(interface, profile="ld3-dev-secoc"))
    n = min(len(secured.rows), len(plain.rows))
    assert secured.rows[n - 1].t > 10.0 and abs(len(secured.rows) - len(plain.rows)) <= 1
    assert secured.summary["can_frames_rejected"] == 0
    assert max_gap(secured.rows[:n], plain.rows[:n]) < TOLERANCE_M


def test_recorded_hil_run_carries_every_can_frame_decoded_by_the_profile(tmp_path):
    from mcap.reader import make_reader

    sc = short_parking_lot(2.0)
    result = run_hil_scenario(sc, tmp_path, LinkConfig(profile="pix-hooke"), record=True)
    with open(tmp_path / "run.mcap", "rb") as f:
        can_msgs = [json.loads(m.data) for _, c, m in make_reader(f).iter_messages(topics=["/can"])]
    s = result.summary
    assert len(can_msgs) == s["can_frames_tx"] + s["can_frames_rx"] == s["can_frames_logged"] > 100
    drive = [m for m in can_msgs if m["id"] == 0x130]
    assert drive and drive[-1]["signals"]["ChassisGearCtrl"] == "D"  # the DBC's gear enum, as a name
    times = [m["t"] for m in can_msgs]
    # stamped with chassis (plant) time: the run's frames, then the hand-back at standstill after it
    assert min(times) == 0.0 and s["sim_time_s"] < max(times) < s["sim_time_s"] + 1.0
