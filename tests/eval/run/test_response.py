"""LD3's attack response in a short closed loop: FusionRipper through the MSF on `local`, the default response
against the paper mode, and the attack-response internals in the outputs."""

import csv
import json

import pytest

from testbed.defense.config import PAPER_MODE
from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import load_scenario
from testbed.rates import Rates

FR = {"kind": "fusionripper", "d": 1.0, "f": 1.5, "start": 15.0}


@pytest.fixture(scope="module")
def fr_runs(tmp_path_factory):
    base = load_scenario("local").with_overrides(duration=32.0, detector="oracle", localization="msf",
                                                 defense="ld3", attack=FR)
    out = tmp_path_factory.mktemp("fr")
    return {name: (run_scenario(base.with_overrides(defense_params=params), out / name).summary, out / name)
            for name, params in (("default", {}), ("paper", dict(PAPER_MODE)))}


def test_default_response_stops_in_lane_where_the_paper_mode_straddles(fr_runs):
    default, paper = fr_runs["default"][0], fr_runs["paper"][0]
    assert default["detected"] and paper["detected"]
    assert default["detection_time_s"] < paper["detection_time_s"]  # the refit CUSUM alarms first
    assert default["consequence"] == "stop_in_lane"
    assert abs(default["ar_stop_dev_m"]) < default["lane_straddle_dev_m"]
    assert paper["consequence"] == "stop_with_lane_straddle"
    assert default["defense_params"]["heading"] == "fused" and paper["defense_params"]["heading"] == "msf"


def test_attack_response_internals_are_written(fr_runs):
    summary, run_dir = fr_runs["default"]
    with (run_dir / "trajectory.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    internals = ("fused_dev", "r_ld", "k_msf", "k_ld", "heading_used")
    for row in rows:
        assert all((row[c] != "") == (row["mode"] == "ar") for c in internals), row
        # R^MSF is empty outside the response and where the step left the MSF out (its gain then 0)
        assert (row["r_msf"] != "") == (row["mode"] == "ar" and float(row["k_msf"] or 0) > 0), row
    every = Rates().camera_every  # camera at 20 Hz: a fresh detection every `every` control ticks
    assert every > 1 and [r["ld_fresh"] for r in rows[:2 * every + 1]] == (["1"] + ["0"] * (every - 1)) * 2 + ["1"]
    ar = [r for r in rows if r["mode"] == "ar"]
    assert ar and float(ar[0]["t"]) == pytest.approx(summary["detection_time_s"])
    # the response keeps the MSF until it strays from the odometry-carried deviation, then leaves it out for good
    kept = [float(r["k_msf"]) > 0.0 for r in ar]
    assert kept[0] and not kept[-1] and kept == sorted(kept, reverse=True)
    assert "msf-disowned" in {f["kind"] for f in summary["faults"]}
    assert all(0.0 < float(r["k_ld"]) < 1.0 for r in ar) and all(float(r["k_msf"]) < 1.0 for r in ar)
    # the fused heading stays within a few hundredths of a radian of the lane
    assert max(abs(float(r["heading_used"])) for r in ar) <= 0.05
    assert (run_dir / "ar_fusion.png").stat().st_size > 10_000
    assert json.loads((run_dir / "summary.json").read_text())["defense_params"]["heading_clamp"] == 0.02


def test_no_fusion_plot_without_attack_response(tmp_path):
    sc = load_scenario("urban-straight").with_overrides(duration=3.0, defense="ld3", localization="msf")
    run_scenario(sc, tmp_path)
    assert not (tmp_path / "ar_fusion.png").exists() and (tmp_path / "birdseye.png").exists()


def test_reported_p_source_is_refused_with_a_detector_that_reports_no_variance():
    from testbed.eval.run.runner import SimRun
    from testbed.eval.run.scenario import ScenarioError

    sc = load_scenario("slr").with_overrides(duration=1.0, defense="ld3", detector="classical",
                                             defense_params={"p_source": "reported"})
    with pytest.raises(ScenarioError, match=r"reports its c0 variance.*use detector oracle"):
        SimRun(sc)


def test_p_source_is_refused_for_a_defense_without_the_fusion():
    from testbed.eval.run.scenario import ScenarioError

    with pytest.raises(ScenarioError, match=r"p_source: not read by defense 'ld3-naive-ar'"):
        load_scenario("slr").with_overrides(defense="ld3-naive-ar", detector="classical",
                                            defense_params={"p_source": "reported"})
