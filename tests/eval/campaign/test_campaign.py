"""Campaign plumbing: custom executors, resuming, failures; the run lists of the grid and ROC campaigns."""

import csv
import json
from collections import Counter
from pathlib import Path

import pytest

from testbed.defense.config import PAPER_MODE, DefenseConfig
from testbed.errors import UserError
from testbed.eval.campaign.driver import CampaignRun, run_campaign
from testbed.eval.experiments.ablation import ATTACKS, VARIANTS, ablation_runs, is_default
from testbed.eval.experiments.campaigns import (
    CAMPAIGNS,
    GRID_D,
    GRID_F,
    GRID_TRACK_SEEDS,
    fr_grid_runs,
    fusionripper_ld3_runs,
)
from testbed.eval.experiments.roc import record_detection_run, roc_runs
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import SCHEMA_VERSION, RunSummary
from tests.eval.run.summary_helpers import fake_summary
from tests.eval.run.summary_helpers import write_fake_summary as write_summary


def write_fake_summary(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Executor double: fails for runs tagged `fail`, else writes a summary counting its calls."""
    if run.tags.get("fail"):
        raise RuntimeError("boom")
    calls = run_dir.parent / "calls.txt"
    calls.write_text(calls.read_text() + run.run_id + "\n" if calls.exists() else run.run_id + "\n")
    return write_summary(run_dir, scenario=run.run_id)


def test_custom_executor_resume_and_failures(tmp_path):
    sc = load_scenario("slr")
    runs = [CampaignRun("a", sc, {"k": 1}), CampaignRun("b", sc, {"k": 2, "fail": True}), CampaignRun("c", sc, {})]
    done = run_campaign(runs, tmp_path, workers=1, progress=False, execute=write_fake_summary)
    assert [(r.run_id, s.scenario) for r, s in done] == [("a", "a"), ("c", "c")]
    assert all(isinstance(s, RunSummary) for _, s in done)
    assert "b: RuntimeError: boom" in (tmp_path / "failures.txt").read_text()
    with (tmp_path / "runs.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["run_id"], r["k"], r["scenario"], r["consequence"]) for r in rows] == [
        ("a", "1", "a", "reach_destination"), ("c", "", "c", "reach_destination")]
    run_campaign(runs[:1] + runs[2:], tmp_path, workers=1, progress=False, execute=write_fake_summary)
    assert (tmp_path / "calls.txt").read_text().split() == ["a", "c"]  # the rerun resumed: nothing ran twice


def test_a_run_whose_summary_is_not_of_this_version_is_named_in_one_line(tmp_path):
    sc = load_scenario("slr")
    runs = [CampaignRun("a", sc, {}), CampaignRun("b", sc, {})]
    run_campaign(runs, tmp_path, workers=1, progress=False, execute=write_fake_summary)
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    del summary["max_abs_dev_m"]
    (tmp_path / "b" / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(UserError, match=r"b/summary.json .*max_abs_dev_m") as err:
        run_campaign(runs, tmp_path, workers=1, progress=False, execute=write_fake_summary)
    assert "\n" not in str(err.value)
    summary["max_abs_dev_m"] = "far"
    (tmp_path / "b" / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(UserError, match=r"b/summary.json .*max_abs_dev_m"):
        run_campaign(runs, tmp_path, workers=1, progress=False, execute=write_fake_summary)


def test_grid_runs_cover_every_cell_with_20_drives_drive_outermost():
    runs = fr_grid_runs("oracle")
    assert len({r.run_id for r in runs}) == len(runs) == 2 * len(GRID_D) * len(GRID_F) * 20
    cells = Counter((r.tags["track"], r.tags["d"], r.tags["f"]) for r in runs)
    assert set(cells.values()) == {20}
    first = runs[: len(cells)]
    assert {(r.tags["track"], r.tags["d"], r.tags["f"]) for r in first} == set(cells)
    assert {r.tags["start"] for r in first} == {8.0}
    assert all(r.scenario.defense == "none" and r.scenario.localization == "msf" for r in runs)
    # each cell's drives vary the start time, the sensor-noise seed and the road layout
    cell = [r for r in runs if (r.tags["track"], r.tags["d"], r.tags["f"]) == ("local", 1.0, 1.5)]
    assert len({r.scenario.seed for r in cell}) == 20 and len({r.tags["start"] for r in cell}) == 20
    assert {r.scenario.track for r in cell} == {f"local@{s}" for s in GRID_TRACK_SEEDS}


def test_fusionripper_ld3_runs_use_held_out_layouts_noise_seeds_and_start_times():
    runs = fusionripper_ld3_runs("oracle")
    assert len(runs) == len({r.run_id for r in runs}) == 2 * 3 * 3 * 5
    assert not any(r.scenario.track in ("local", "highway", "local@0", "highway@0") for r in runs)
    assert {r.scenario.seed for r in runs} == {1, 2, 3}
    assert all(r.scenario.defense == "ld3" and r.scenario.defense_params == {} for r in runs)


def test_ablation_runs_put_every_variant_on_every_attack_and_held_out_road():
    runs = ablation_runs("neural")
    per_variant = Counter(r.tags["variant"] for r in runs)
    assert list(per_variant) == list(VARIANTS) and next(iter(VARIANTS)) == "paper"
    assert len(set(per_variant.values())) == 1
    assert {r.tags["attack"] for r in runs} == set(ATTACKS)
    assert all(r.scenario.detector == "oracle" and "@" in r.scenario.track for r in runs)
    paper = [r for r in runs if r.tags["variant"] == "paper"]
    assert all(r.scenario.defense_params == PAPER_MODE for r in paper)
    assert sum(is_default(v) for v in VARIANTS.values()) == 1  # the shipped default is one measured variant
    assert not is_default(PAPER_MODE)
    for run in runs[:: max(1, len(runs) // 40)]:  # every variant's overrides are valid [defense] tables
        DefenseConfig.from_dict(run.scenario.defense_params)


def test_roc_campaign_records_benign_fit_and_attacked_drives():
    assert CAMPAIGNS.get("roc").execute is record_detection_run
    runs = roc_runs("oracle")
    roles = Counter((r.tags["track"], r.tags["role"]) for r in runs)
    assert roles == {("local", "benign"): 10, ("local", "fit"): 2, ("local", "attacked"): 10,
                     ("highway", "benign"): 10, ("highway", "fit"): 2, ("highway", "attacked"): 10}
    for r in runs:
        assert r.scenario.defense == "none" and r.scenario.detector == "oracle"
        assert (r.scenario.attack is None) == (r.tags["role"] != "attacked")


def test_attack_success_is_the_goal_deviation_or_leaving_the_road():
    from testbed.eval.run.consequence import attack_succeeded

    assert attack_succeeded("highway", 1.95, "out_of_lane")
    assert not attack_succeeded("highway", 1.85, "out_of_lane")
    assert attack_succeeded("local", 0.8, "hit_curb")  # the curb stops the car before the 1.3 m goal
    assert not attack_succeeded("local", 1.2, "stop_with_lane_straddle")
    assert not attack_succeeded("local", None, "reach_destination")


def test_benign_table_reports_msf_lateral_error_per_track(tmp_path):
    from testbed.eval.experiments.campaigns import benign_table
    from testbed.eval.run.outputs import TRAJECTORY_COLUMNS

    sc = load_scenario("local")
    done = []
    for seed, err in ((0, (0.0, 0.1, -0.2)), (1, (0.05, 0.05, 0.05))):
        run = CampaignRun(f"local-seed{seed}", sc, {"track": "local", "seed": seed})
        run_dir = tmp_path / run.run_id
        run_dir.mkdir()
        rows = [",".join(TRAJECTORY_COLUMNS)]
        for e in err:  # phys_dev 0.3, msf_dev 0.3 + e: the MSF lateral error is e
            values = {c: "0" for c in TRAJECTORY_COLUMNS} | {"phys_dev": "0.3", "msf_dev": str(0.3 + e)}
            rows.append(",".join(values[c] for c in TRAJECTORY_COLUMNS))
        (run_dir / "trajectory.csv").write_text("\n".join(rows) + "\n")
        done.append((run, fake_summary(detected=False, max_abs_dev_m=0.1, consequence="reach_destination")))
    row = next(line for line in benign_table(done, tmp_path).splitlines() if line.startswith("| local"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[5] == "0.129 (worst run)"  # sqrt((0 + 0.01 + 0.04) / 3)
    assert cells[6] == "0.200"


def test_a_sweep_over_defense_b_is_recorded_in_runs_csv(tmp_path):
    import csv

    base = load_scenario("slr").with_overrides(duration=1.0, defense="ld3", localization="msf")
    runs = [CampaignRun(f"b{b:g}", base.with_overrides(defense_params={"b": b}), {"b": b}) for b in (0.45, 0.6)]
    run_campaign(runs, tmp_path, workers=1, progress=False)
    with (tmp_path / "runs.csv").open() as fh:
        rows = {r["run_id"]: r for r in csv.DictReader(fh)}
    assert (rows["b0.45"]["defense_params.b"], rows["b0.6"]["defense_params.b"]) == ("0.45", "0.6")
    assert rows["b0.45"]["resolved_scenario.defense_params.window"] == "5"
    assert rows["b0.45"]["schema_version"] == str(SCHEMA_VERSION) and json.loads(rows["b0.6"]["faults"]) == []


def test_roc_report_with_only_a_fit_drive_says_there_is_nothing_to_sweep(tmp_path):
    from testbed.eval.experiments.campaigns import run_named

    report = run_named("roc", tmp_path, detector="oracle", workers=1, progress=False, select="local-fit-seed100")
    text = report.read_text()
    assert "fitted on 1 benign drives" in text and "no ROC to sweep yet" in text
