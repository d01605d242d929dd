"""The campaigns added for the paper report: run lists (sim-table, stealthy, drp-ar) and their tables over
summaries of known values; comma-separated `--runs` globs."""

import csv
from pathlib import Path

import pytest

from testbed.defense.config import PAPER_CUSUM, DefenseConfig
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.campaigns import CAMPAIGNS, selected_runs
from testbed.eval.experiments.drp_response import PATCH_AT, TRACE_ROADS, drp_runs, drp_table
from testbed.eval.experiments.paper_report import load_paper_values
from testbed.eval.experiments.sim_table import (
    BENIGN_SEEDS,
    SIM_DEFENSES,
    SIM_SCENARIOS,
    SIM_STARTS,
    sim_table,
    sim_table_runs,
)
from testbed.eval.experiments.stealthy_bound import (
    LD_NOISE_STD,
    MARGINS_SIGMA,
    fluctuation_stats,
    paper_bound,
    stealthy_runs,
)
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary
from tests.eval.run.summary_helpers import fake_summary


def summary(**fields) -> RunSummary:
    base = {"consequence": "stop_in_lane", "detected": True, "detection_dev_m": 0.3, "max_abs_dev_m": 0.5,
            "ar_max_dev_m": 0.5, "ar_stop_dev_m": -0.4, "final_dev_m": -0.4, "lane_straddle_dev_m": 0.83}
    return fake_summary(**{**base, **fields})


def test_sim_table_runs_cover_every_scenario_setting_and_start():
    runs = sim_table_runs("oracle")
    per_scenario = len(SIM_DEFENSES) * len(SIM_STARTS) + len(BENIGN_SEEDS)
    assert len(runs) == len({r.run_id for r in runs}) == len(SIM_SCENARIOS) * per_scenario == 160
    for r in runs:
        preset, speed = SIM_SCENARIOS[r.tags["scenario"]]
        assert r.scenario.track == preset and r.scenario.speed == speed and r.scenario.localization == "msf"
        if r.tags["setting"] == "benign":
            assert r.scenario.attack is None and r.scenario.defense == "ld3"
        else:
            assert r.scenario.defense == r.tags["setting"]
            assert r.scenario.attack == {"kind": "trace", "trace": "default", "start": r.tags["start"]}
            assert r.scenario.duration == r.tags["start"] + 20.0
    assert {r.scenario.speed for r in runs if r.scenario.track == "slr"} == {10.0, 20.0}


def test_sim_table_groups_by_scenario_and_setting():
    sc = load_scenario("slr")
    done = [(CampaignRun(f"slr-low/ld3-start{k}", sc, {"scenario": "slr-low", "setting": "ld3"}),
             summary(max_abs_dev_m=v)) for k, v in enumerate((0.4, 0.6))]
    done.append((CampaignRun("slr-low/none-start6", sc, {"scenario": "slr-low", "setting": "none"}),
                 summary(max_abs_dev_m=3.0, detected=False, consequence="fall_off_road")))
    table = sim_table(done, Path("."))
    assert "| slr-low | ld3 | 2 | 0.83 | 0.50, 0.10 | 2/2 | stop_in_lane ×2 |" in table
    assert "| slr-low | none | 1 | 0.83 | 3.00, 0.00 | 0/1 | fall_off_road ×1 |" in table
    assert table.index("| slr-low | ld3 |") < table.index("| slr-low | none |")


def test_stealthy_runs_use_each_detectors_noise_and_margins():
    runs = stealthy_runs("neural")
    assert len({r.run_id for r in runs}) == len(runs)
    for r in runs:
        sigma = LD_NOISE_STD[r.tags["detector"]][r.tags["track"]]
        assert r.scenario.detector == r.tags["detector"] and r.scenario.defense == "ld3"
        assert r.scenario.attack["ld_std"] == sigma
        assert r.scenario.attack["margin"] == pytest.approx(r.tags["margin_sigma"] * sigma)
    oracle = {r.tags["margin_sigma"] for r in runs if r.tags["detector"] == "oracle"}
    assert oracle == {0.0}  # a noiseless detector: every margin would be the same run
    assert {r.tags["margin_sigma"] for r in runs if r.tags["detector"] == "neural"} == set(MARGINS_SIGMA)


def test_paper_bound_reproduces_the_papers_stealthy_table():
    for row in load_paper_values()["stealthy"]["rows"]:
        assert paper_bound(*row["fluctuation"], DefenseConfig(**PAPER_CUSUM)) == pytest.approx(
            row["bound"], abs=0.006), row["trace"]


def write_trajectory(run_dir: Path, rows: list[dict]) -> None:
    run_dir.mkdir(parents=True)
    with (run_dir / "trajectory.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_fluctuation_is_measured_on_fresh_detections_before_the_attack(tmp_path):
    sc = load_scenario("local")
    rows = [{"t": t / 10, "phys_dev": 0.1, "ld_dev": 0.1 + (0.2 if t % 2 else -0.1), "ld_fresh": 1}
            for t in range(100)]
    rows += [{"t": 10.0 + t / 10, "phys_dev": 0.0, "ld_dev": 5.0, "ld_fresh": 1} for t in range(10)]  # attacked
    rows += [{"t": 0.05, "phys_dev": 0.0, "ld_dev": 9.0, "ld_fresh": 0}]  # not a fresh detection
    write_trajectory(tmp_path / "a", rows)
    mu, sigma = fluctuation_stats(tmp_path, [CampaignRun("a", sc, {"start": 10.0})])
    assert mu == pytest.approx(0.15) and sigma == pytest.approx(0.05)


def test_drp_runs_trace_per_road_and_patch_reached_before_the_end():
    runs = drp_runs("neural")
    assert len({r.run_id for r in runs}) == len(runs)
    traces = [r for r in runs if r.tags["attack"] == "drp-trace"]
    patches = [r for r in runs if r.tags["attack"] == "drp-patch"]
    assert {r.tags["road"] for r in traces} == set(TRACE_ROADS)
    assert {r.scenario.attack["at"] for r in patches} == set(PATCH_AT)
    for r in patches:
        reach_s = (r.scenario.attack["at"] - r.scenario.start_s) / r.scenario.speed
        assert 0 < reach_s < r.scenario.duration - 10.0
    assert all(r.scenario.defense == "ld3" and r.scenario.detector == "neural" for r in runs)


def test_drp_table_counts_alarms_and_takes_response_deviations_from_alarmed_runs():
    sc = load_scenario("local")
    done = [(CampaignRun("drp-patch/a", sc, {"attack": "drp-patch", "road": "urban-straight"}),
             summary(detected=False, ar_max_dev_m=None, ar_stop_dev_m=None, max_abs_dev_m=0.1,
                     consequence="reach_destination")),
            (CampaignRun("drp-patch/b", sc, {"attack": "drp-patch", "road": "urban-straight"}),
             summary(ar_max_dev_m=0.2, ar_stop_dev_m=0.1, max_abs_dev_m=0.2))]
    table = drp_table(done, Path("."))
    assert ("| drp-patch | urban-straight | 2 | 1/2 | 0.20, 0.00 | 0.10, 0.00 | 0.15, 0.05 | 0.83 "
            "| reach_destination ×1, stop_in_lane ×1 |") in table


def test_runs_take_comma_separated_globs():
    runs = selected_runs("sim-table", "oracle", "slr-low/ld3-start6, urban-curvy/benign-seed[01]")
    assert [r.run_id for r in runs] == ["slr-low/ld3-start6", "urban-curvy/benign-seed0", "urban-curvy/benign-seed1"]
    with pytest.raises(ValueError, match="matches no run"):
        selected_runs("sim-table", "oracle", "nothing-*")


def test_new_campaigns_are_registered():
    assert {"sim-table", "stealthy", "drp-ar"} <= set(CAMPAIGNS.names())
