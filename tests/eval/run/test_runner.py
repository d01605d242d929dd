"""Short closed loops on every preset, the output contract, determinism across processes, CLI errors."""

import csv
import json
import re
import subprocess
import sys

import pytest

from testbed.eval.run.outputs import TRAJECTORY_COLUMNS
from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import ScenarioError, load_scenario
from testbed.eval.run.summary import RunSummary
from testbed.rates import CONTROL_HZ

PRESETS = ("slr", "urban-straight", "urban-curvy", "highway", "local", "parking-lot")


@pytest.mark.parametrize("preset", PRESETS)
def test_short_closed_loop_keeps_lane_and_writes_contract(preset, tmp_path):
    sc = load_scenario(preset).with_overrides(duration=6.0)
    result = run_scenario(sc, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary.keys() == RunSummary.model_fields.keys() and summary["schema_version"] == 8
    assert summary["consequence"] == "reach_destination" and summary["ended_by"] == "duration"
    assert summary["max_abs_dev_m"] < 0.10
    assert summary["attack"] is None and summary["detected"] is False
    with (tmp_path / "trajectory.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0].keys()) == TRAJECTORY_COLUMNS
    assert len(rows) == len(result.rows) == round(6.0 * CONTROL_HZ)
    speeds = [float(r["speed"]) for r in rows]
    assert speeds[-1] > 2.0, "the car drives off under physics"
    assert (tmp_path / "birdseye.png").stat().st_size > 10_000


def test_a_run_that_reaches_the_end_of_the_road_says_so_before_its_duration(tmp_path):
    summary = run_scenario(load_scenario("parking-lot").with_overrides(duration=120.0), tmp_path).summary
    assert summary["consequence"] == "reach_destination" and summary["ended_by"] == "road_end"
    assert summary["sim_time_s"] < 60.0


def test_a_car_steered_off_the_map_ends_in_a_departure_not_an_internal_error(tmp_path):
    # SAVIOR steers on the MSF, which the attack moves 9 m aside: the car leaves the parking lot's map, where the
    # road-end check could not place it and the run stopped with an OffMapError
    sc = load_scenario("parking-lot").with_overrides(
        duration=20.0, defense="savior", detector="oracle", localization="msf",
        attack={"kind": "offmap", "start": 5.0378, "distance": 9.3547, "ramp": 2.1766})
    summary = run_scenario(sc, tmp_path).summary
    assert summary["consequence"] == "out_of_lane" and summary["max_abs_dev_m"] > 3.0


def test_same_seed_gives_identical_trajectory_in_two_processes(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        cmd = [sys.executable, "-m", "testbed.cli", "run", "urban-curvy", "--duration", "4", "--seed", "3",
               "--localization", "msf", "--out", str(out)]
        subprocess.run(cmd, check=True, capture_output=True)
        outs.append((out / "trajectory.csv").read_bytes())
    assert outs[0] == outs[1]


def test_attacked_run_without_defense_leaves_lane_and_ld3_stops_in_it(tmp_path):
    base = load_scenario("urban-straight").with_overrides(
        duration=25.0, attack={"kind": "trace", "trace": "default", "start": 5.0})
    none = run_scenario(base.with_overrides(defense="none"), tmp_path / "none").summary
    ld3 = run_scenario(base.with_overrides(defense="ld3"), tmp_path / "ld3").summary
    assert none["consequence"] in ("hit_curb", "out_of_lane", "hit_barrier")
    assert none["ended_by"] == ("duration" if none["consequence"] == "out_of_lane" else "consequence")
    assert ld3["detected"] and ld3["consequence"] == "stop_in_lane" and ld3["ended_by"] == "standstill"
    assert abs(ld3["ar_stop_dev_m"]) < ld3["lane_straddle_dev_m"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "no-such-scenario"], "unknown scenario"),
        (["run", "slr", "--track", "moon"], "unknown"),
        (["run", "parking-lot", "--speed", "20"], "cannot reach|beyond"),
        (["run", "slr", "--out", "/proc/forbidden"], "cannot write"),
        (["run", "slr", "--condition", "fog"], "unknown condition"),
        (["run", "slr", "--attack", "teleport:x=1"], "attack"),
    ],
)
def test_bad_input_gives_one_line_and_exit_2(args, message):
    proc = subprocess.run([sys.executable, "-m", "testbed.cli", *args], capture_output=True, text=True)
    assert proc.returncode == 2
    err = [line for line in proc.stderr.splitlines() if line.startswith("ld3: error:")]
    assert len(err) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert re.search(message, err[0]), err[0]


def test_malformed_toml_is_a_scenario_error(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("track = [")
    with pytest.raises(ScenarioError):
        load_scenario(str(bad))


def test_savior_in_the_loop_models_the_scenario_vehicle():
    """SAVIOR's bicycle model predicts with the wheelbase of the car it guards, not a generic one."""
    from testbed.eval.run.runner import SimRun
    from vehicles.params import get_vehicle

    for vehicle in ("sedan", "dev-chassis"):
        sc = load_scenario("parking-lot").with_overrides(vehicle=vehicle, defense="savior", detector="oracle",
                                                        localization="msf", speed=3.0)
        sim = SimRun(sc)
        try:
            assert sim.parts.defense.model.c.wheelbase == get_vehicle(vehicle).wheelbase
        finally:
            sim.close()


def test_debug_shows_the_traceback_that_the_one_line_error_hides():
    plain = subprocess.run([sys.executable, "-m", "testbed.cli", "run", "no-such-scenario"], capture_output=True,
                           text=True)
    debug = subprocess.run([sys.executable, "-m", "testbed.cli", "--debug", "run", "no-such-scenario"],
                           capture_output=True, text=True)
    assert plain.returncode == 2 and "Traceback" not in plain.stderr and "unknown scenario" in plain.stderr
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "ScenarioError" in debug.stderr


def test_compare_tables_any_runs_and_names_what_differs(tmp_path):
    from testbed.eval.report.compare import compare_runs

    base = load_scenario("slr").with_overrides(duration=2.0, defense="ld3", localization="msf")
    run_scenario(base, tmp_path / "a")
    run_scenario(base.with_overrides(defense_params={"heading": "msf", "window": 20}), tmp_path / "b")
    report = compare_runs([tmp_path / "a", tmp_path / "b"], tmp_path / "cmp").read_text()
    assert "heading = fused, window = 5" in report and "heading = msf, window = 20" in report
    assert report.count("| reach_destination |") == 2 and (tmp_path / "cmp" / "deviations.png").stat().st_size > 5000
    with pytest.raises(ValueError, match="not a finished run"):
        compare_runs([tmp_path / "nowhere"], tmp_path / "cmp")


def test_an_internal_error_is_reported_as_a_bug_not_as_a_user_error(monkeypatch, capsys):
    """A plain ValueError from inside the testbed is a bug: exit 70 naming --debug, never the exit 2 of a
    user error; a UserError stays a one-line exit 2."""
    from testbed import cli
    from testbed.errors import UserError

    def broken(args):
        raise ValueError("math domain error")

    def refused(args):
        raise UserError("speed must be > 0 m/s")

    for func, code, text in ((broken, 70, "internal error (a bug, not your input): ValueError: math domain error"),
                             (refused, 2, "ld3: error: speed must be > 0 m/s")):
        monkeypatch.setattr(cli, "cmd_components", func)
        assert cli.main(["components"]) == code
        assert text in capsys.readouterr().err
    with pytest.raises(ValueError, match="math domain"):
        monkeypatch.setattr(cli, "cmd_components", broken)
        cli.main(["--debug", "components"])
