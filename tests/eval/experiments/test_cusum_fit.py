"""The CUSUM refit campaign: its offline sweep against hand-computed CUSUMs, and the campaign end to end on
two short recorded drives."""

import numpy as np
import pytest

from testbed.conditions import CONDITIONS
from testbed.defense.config import DefenseConfig
from testbed.defense.roc import ResidualSeries
from testbed.eval.campaign.driver import CampaignRun, run_campaign
from testbed.eval.experiments.cusum_fit import (
    FIT_PRESETS,
    FIT_SEEDS,
    benign_alarms,
    cusum_check_runs,
    cusum_fit_runs,
    cusum_fit_table,
    detection_dev,
    earliest_clean_pair,
    largest_benign_cusum,
    smallest_clean_b,
    sweep,
)
from testbed.eval.experiments.roc import record_detection_run
from testbed.perception.training.seeds import HELD_OUT_SEEDS


def series(r, t0=0.0, attack_start=None, dt=0.05):
    r = np.asarray(r, dtype=float)
    return ResidualSeries(t0 + dt * np.arange(len(r)), r, np.zeros(len(r), dtype=int), attack_start)


def test_largest_benign_cusum_by_hand():
    # b = 0.2: S = 0.1, 0.4, 0.2, 0.0 ; and 0.0, 0.3 -> largest 0.4
    benign = [series([0.3, 0.5, 0.0, 0.0]), series([-0.1, -0.5])]
    assert largest_benign_cusum(benign, 0.2) == pytest.approx(0.4)
    assert largest_benign_cusum(benign, 0.5) == pytest.approx(0.0)


def test_detection_dev_is_the_largest_true_deviation_up_to_the_first_alarm_after_the_start():
    s = series([0.0, 0.0, 1.0, 1.0, 1.0], attack_start=0.1)  # t = 0, .05, .1, .15, .2
    t = np.array([0.0, 0.05, 0.1, 0.15, 0.2])
    phys = np.array([0.1, -0.3, 0.2, 0.5, 0.9])
    # b = 0.5, τ = 0.6: S = 0, 0, 0.5, 1.0 -> alarm at t = 0.15; largest |dev| up to there 0.5
    assert detection_dev(s, t, phys, 0.5, 0.6) == pytest.approx(0.5)
    # τ = 2: S reaches 1.5 at most, no alarm
    assert np.isnan(detection_dev(s, t, phys, 0.5, 2.0))
    early = series([1.0, 1.0, 0.0, 0.0, 0.0], attack_start=0.1)  # alarms at t = 0.05, before the start
    assert np.isnan(detection_dev(early, t, phys, 0.5, 0.4))


def test_sweep_and_the_smallest_clean_b():
    benign = [series([0.35, 0.35, 0.35, 0.35])]  # largest CUSUM (0.35 - b) × 4 for b < 0.35
    t = 0.05 * np.arange(8)
    attacked = [(series([0.0, 0.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0], attack_start=0.1), t, 0.1 * np.arange(8))]
    rows = sweep(benign, attacked, np.array([0.0, 0.1, 0.3, 0.35, 3.0]), tau=0.1)
    by_b = {r["b"]: r for r in rows}
    assert by_b[0.0]["largest_benign_cusum"] == pytest.approx(1.4)
    assert by_b[0.3]["largest_benign_cusum"] == pytest.approx(0.2)
    assert by_b[0.35]["largest_benign_cusum"] == pytest.approx(0.0)
    assert [by_b[b]["false_alarms"] for b in (0.0, 0.1, 0.3, 0.35)] == [1, 1, 1, 0]
    assert by_b[0.35]["detected"] == 1 and by_b[0.35]["detection_dev_max"] == pytest.approx(0.2)
    assert by_b[3.0]["detected"] == 0 and np.isnan(by_b[3.0]["detection_dev_mean"])
    assert smallest_clean_b(rows, tau=0.1)["b"] == 0.35
    assert smallest_clean_b(rows, tau=0.1, headroom=2.0)["b"] == 0.35
    assert smallest_clean_b(rows[:3], tau=0.1) is None


def test_the_smallest_clean_tau_of_each_b_and_the_earliest_clean_pair():
    benign = [series([0.35, 0.35, 0.35, 0.35])]  # largest CUSUM (0.35 - b) × 4 for b < 0.35, else 0
    t = 0.05 * np.arange(8)
    ramp = series([0.0, 0.0, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9], attack_start=0.1)
    attacked = [(ramp, t, 0.1 * np.arange(8))]
    rows = sweep(benign, attacked, np.array([0.0, 0.1, 0.3, 0.35, 3.0]), tau=0.1)
    by_b = {r["b"]: r for r in rows}
    # b = 0: τ = 1.4, S = 0.4, 0.9, 1.5 -> alarm at index 4 (|dev| 0.4); b = 0.1: τ = 1.0, S = 0.3, 0.7, 1.2 -> 4;
    # b = 0.3: τ = 0.2, S = 0.1, 0.3 -> 3; b = 0.35: τ = 0, S = 0.05 -> 2; b = 3: never
    assert [by_b[b]["clean_tau_detection_dev_max"] for b in (0.0, 0.1, 0.3, 0.35)] == pytest.approx(
        [0.4, 0.4, 0.3, 0.2])
    assert by_b[3.0]["clean_tau_detected"] == 0 and np.isnan(by_b[3.0]["clean_tau_detection_dev_max"])
    assert by_b[0.1]["detection_dev_max"] == pytest.approx(0.2)  # at τ = 0.1 it alarms at index 2
    assert earliest_clean_pair(rows)["b"] == 0.35
    assert earliest_clean_pair(rows[:3])["b"] == 0.3
    assert earliest_clean_pair(rows[4:]) is None


def test_benign_alarms_name_the_drive_the_alarm_time_and_the_largest_residual():
    quiet, loud = cusum_fit_runs("oracle")[:2]
    benign = [(quiet, series([0.1] * 10)), (loud, series([0.1] * 5 + [0.9, 0.95, 0.2]))]
    # b = 0.6: S = 0.3 at index 5 (t = 0.25 s) is over τ = 0.1; the largest |r| is 0.95 at index 6
    ((run, alarm, largest, at),) = benign_alarms(benign, 0.6, 0.1)
    assert run is loud
    assert alarm == pytest.approx(0.25) and largest == pytest.approx(0.95) and at == pytest.approx(0.30)
    assert benign_alarms(benign, 1.0, 0.1) == []


def test_the_campaign_drives_every_preset_and_condition_on_held_out_layouts():
    runs = cusum_fit_runs("neural")
    benign = [r for r in runs if r.tags["role"] == "benign"]
    assert len(benign) == len(FIT_PRESETS) * len(CONDITIONS) * len(FIT_SEEDS)
    pairs = {(r.tags["preset"], r.tags["condition"]) for r in benign}
    assert pairs == {(p, c) for p in FIT_PRESETS for c in CONDITIONS}
    assert all("@" in r.scenario.track and r.scenario.defense == "none" for r in benign)
    attacked = [r for r in runs if r.tags["role"] == "attacked"]
    assert [r.scenario.attack["start"] for r in attacked] == [6.0, 8.0, 10.0, 12.0, 14.0]
    assert len({r.run_id for r in runs}) == len(runs)


def test_the_check_campaign_drives_what_the_fit_never_drove():
    fit, check = cusum_fit_runs("neural"), cusum_check_runs("neural")
    benign = [r for r in check if r.tags["role"] == "benign"]
    assert {(r.tags["preset"], r.tags["condition"]) for r in benign} == {(p, c) for p in FIT_PRESETS
                                                                        for c in CONDITIONS}
    fit_tracks = {r.scenario.track for r in fit if r.tags["role"] == "benign"}
    check_tracks = {r.scenario.track for r in benign}
    assert len(check_tracks) == len(FIT_PRESETS) * len(CONDITIONS) and not fit_tracks & check_tracks
    assert all(int(t.split("@")[1]) in HELD_OUT_SEEDS for t in check_tracks)
    assert not {r.scenario.seed for r in benign} & set(FIT_SEEDS)
    attacked = [r for r in check if r.tags["role"] == "attacked"]
    assert len(attacked) == 10 and not {r.scenario.seed for r in attacked} & {0}
    assert len({r.run_id for r in check}) == len(check)


def test_the_campaign_end_to_end_on_two_short_drives(tmp_path):
    runs = {r.run_id: r for r in cusum_fit_runs("oracle")}
    picked = [runs["benign/urban-straight-day-seed0"], runs["trace/start6"]]
    short = [CampaignRun(r.run_id, r.scenario.with_overrides(duration=12.0), r.tags) for r in picked]
    done = run_campaign(short, tmp_path, workers=1, progress=False, execute=record_detection_run)
    assert len(done) == 2
    text = cusum_fit_table(done, tmp_path)
    assert "1 benign drives, 1 attacked" in text
    assert (tmp_path / "cusum_fit.png").stat().st_size > 0
    header, *rows = (tmp_path / "cusum_fit.csv").read_text().splitlines()
    assert header.split(",")[:3] == ["b", "largest_benign_cusum", "false_alarms"]
    assert len(rows) > 20
    assert "| urban-straight | " in text
    shipped = DefenseConfig()
    assert f"Benign drives that alarm (τ = {shipped.tau:g})" in text and f"| {shipped.b:g} | " in text
    assert "Earliest alarm over (b, τ) with no benign alarm" in text
