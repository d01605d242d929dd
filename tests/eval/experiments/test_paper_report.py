"""`ld3 paper`: the experiment plan (quick globs, estimate, commands) and the report builder over runs of known
values; end to end on a tiny selection (slow)."""

import csv
from pathlib import Path

import pytest

from testbed.cli import main
from testbed.defense.config import DefenseConfig
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments import paper
from testbed.eval.experiments.campaigns import CAMPAIGNS
from testbed.eval.experiments.paper import EXPERIMENTS, PaperOptions, announce_plan, campaign_command, planned_runs
from testbed.eval.experiments.paper_report import (
    CampaignResult,
    ar_deceleration,
    load_paper_values,
    residual_max,
    write_paper_report,
)
from testbed.eval.run.scenario import ScenarioError, load_scenario
from testbed.eval.run.summary import RunSummary
from tests.eval.run.summary_helpers import fake_summary

TRAJECTORY = ("t", "speed", "mode", "phys_dev", "msf_dev", "ld_dev", "ld_fresh")


@pytest.fixture
def chassis_registered(tmp_path_factory, monkeypatch):
    """The chassis campaign visible in the registry: through the installed `ld3.campaigns` entry point, or, in a
    checkout installed before it was declared, through a distribution that declares the same entry point."""
    if "chassis" in CAMPAIGNS:
        yield
        return
    root = tmp_path_factory.mktemp("dist")
    info = root / "ld3_chassis_probe-0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ld3-chassis-probe\nVersion: 0\n")
    (info / "entry_points.txt").write_text("[ld3.campaigns]\nchassis = hil.emulator.campaigns:CHASSIS\n")
    monkeypatch.syspath_prepend(str(root))
    CAMPAIGNS.reload_plugins()
    assert "chassis" in CAMPAIGNS
    yield
    CAMPAIGNS.reload_plugins()  # read again once monkeypatch has restored sys.path


def test_quick_set_is_a_proper_subset_that_fills_every_table(chassis_registered, tmp_path):
    quick = planned_runs(PaperOptions(tmp_path, quick=True))
    full = planned_runs(PaperOptions(tmp_path, quick=False))
    assert list(quick) == [e.campaign for e in EXPERIMENTS]
    for name, runs in quick.items():
        assert 0 < len(runs) < len(full[name]), name
        assert {r.run_id for r in runs} <= {r.run_id for r in full[name]}
    cells = {(r.tags["scenario"], r.tags["setting"]) for r in quick["sim-table"]}
    assert len(cells) == 4 * 4  # every scenario × (ld3, naive, none, benign)
    assert {(r.tags["speed"], r.tags["setting"]) for r in quick["chassis"]} == {
        (s, k) for s in (2.0, 4.0) for k in ("ld3", "naive", "none", "benign")}
    assert {r.tags["role"] for r in quick["roc"]} == {"fit", "benign", "attacked"}
    assert {r.tags["attack"] for r in quick["drp-ar"]} == {"drp-trace", "drp-patch"}
    assert {r.tags["attack"] for r in quick["ablation"]} == {"fusionripper", "trace", "drp-trace", "drp-bend",
                                                             "stealthy"}


def test_plan_announces_runs_to_do_and_commands_regenerate_the_selection(chassis_registered, tmp_path):
    options = PaperOptions(tmp_path / "out", quick=True, detector="classical")
    text = announce_plan(planned_runs(options), options)
    total = sum(len(r) for r in planned_runs(options).values())
    assert text.startswith(f"ld3 paper (quick): {total} runs to do, estimated ≤ ")
    assert "  sim-table             16 of    16 runs to do" in text
    command = campaign_command(EXPERIMENTS[0], options)
    assert command == (f"ld3 campaign sim-table --out {tmp_path / 'out' / 'sim-table'} --detector classical "
                       "--runs '*-start10,*/benign-seed0'")


def test_unregistered_campaign_is_refused_naming_the_fix(monkeypatch, tmp_path):
    monkeypatch.setattr(paper, "EXPERIMENTS", (paper.Experiment("no-such-campaign", "*"),))
    with pytest.raises(ValueError, match=r"no-such-campaign not registered.*pip install -e \."):
        planned_runs(PaperOptions(tmp_path))


def test_a_detector_some_experiment_cannot_use_is_refused_naming_the_fix(chassis_registered, tmp_path):
    with pytest.raises(ScenarioError, match=r"drp-ar run drp-patch/urban-straight-at62-seed1: .*--detector neural"):
        planned_runs(PaperOptions(tmp_path, quick=True, detector="oracle"))


def write_run(folder: Path, run_id: str, rows: list[dict]) -> None:
    run_dir = folder / run_id
    run_dir.mkdir(parents=True)
    with (run_dir / "trajectory.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=TRAJECTORY)
        writer.writeheader()
        writer.writerows([{c: row.get(c, "") for c in TRAJECTORY} for row in rows])


def braking_rows(v0: float, decel: float) -> list[dict]:
    """0.5 s of normal driving at v0, then a response braking at `decel` to standstill; MSF − LD = 0.2 m."""
    rows = [{"t": k / 10, "speed": v0, "mode": "normal", "phys_dev": 0, "msf_dev": 0.2, "ld_dev": 0, "ld_fresh": 1}
            for k in range(5)]
    t, v = 0.5, v0
    while v > 0:
        rows.append({"t": t, "speed": v, "mode": "attack_response", "phys_dev": 0, "msf_dev": 0.5, "ld_dev": 0,
                     "ld_fresh": 0})
        t, v = round(t + 0.1, 6), max(0.0, v - decel * 0.1)
    rows.append({"t": t, "speed": 0.0, "mode": "attack_response", "phys_dev": 0, "msf_dev": 0, "ld_dev": 0,
                 "ld_fresh": 0})
    return rows


def test_trajectory_measures(tmp_path):
    write_run(tmp_path, "a", braking_rows(4.0, 2.5))
    assert ar_deceleration(tmp_path / "a") == pytest.approx(2.5, rel=0.03)
    assert residual_max(tmp_path / "a") == pytest.approx(0.2)  # fresh detections only


def result(name: str, folder: Path, done: list) -> CampaignResult:
    return CampaignResult(name, folder / name, f"ld3 campaign {name}", [r for r, _ in done], done)


def summary(**fields) -> RunSummary:
    base = {"consequence": "stop_in_lane", "detected": True, "detection_dev_m": 0.3, "max_abs_dev_m": 0.5,
            "ar_max_dev_m": 0.5, "ar_stop_dev_m": -0.4, "final_dev_m": -0.4, "lane_straddle_dev_m": 0.83,
            "defense": "ld3"}
    return fake_summary(**{**base, **fields})


def test_report_puts_the_papers_values_beside_ours(tmp_path):
    sc = load_scenario("slr")
    sim = [(CampaignRun(f"slr-low/ld3-start{k}", sc, {"scenario": "slr-low", "setting": "ld3", "start": k}),
            summary(max_abs_dev_m=v, detection_dev_m=0.3 + (k - 6) / 10)) for k, v in ((6, 0.4), (7, 0.6))]
    sim.append((CampaignRun("slr-low/benign-seed0", sc, {"scenario": "slr-low", "setting": "benign", "seed": 0}),
                summary(detected=False, max_abs_dev_m=0.05, ar_max_dev_m=None, ar_stop_dev_m=None,
                        consequence="reach_destination")))
    write_run(tmp_path / "sim-table", "slr-low/benign-seed0", braking_rows(0.0, 1.0)[:5])
    chassis = [(CampaignRun(f"4mps/ld3-rep{k}", sc, {"speed": 4.0, "setting": "ld3", "rep": k}),
                summary(detection_dev_m=0.1, ar_max_dev_m=0.3 + 0.1 * k, ar_stop_dev_m=0.2,
                        git_commit=("abcdef0123456789", "0123456789abcdef-dirty")[k])) for k in range(2)]
    for run, _ in chassis:
        write_run(tmp_path / "chassis", run.run_id, braking_rows(4.0, 2.5))
    stealthy = [(CampaignRun("neural/local-margin0sigma-seed1", sc,
                             {"detector": "neural", "track": "local", "margin_sigma": 0.0, "start": 0.4}),
                 summary(detected=False, max_abs_dev_m=0.62, detection_dev_m=None, consequence="reach_destination"))]
    write_run(tmp_path / "stealthy", "neural/local-margin0sigma-seed1", braking_rows(4.0, 2.5))
    drp = [(CampaignRun("drp-trace/local-start10-seed1", sc, {"attack": "drp-trace", "road": "local"}),
            summary(ar_max_dev_m=0.05, ar_stop_dev_m=0.02, max_abs_dev_m=0.05))]
    results = {"sim-table": result("sim-table", tmp_path, sim), "chassis": result("chassis", tmp_path, chassis),
               "fusionripper-ld3": result("fusionripper-ld3", tmp_path, []),
               "fusionripper-grid": result("fusionripper-grid", tmp_path, []),
               "roc": result("roc", tmp_path, []), "stealthy": result("stealthy", tmp_path, stealthy),
               "drp-ar": result("drp-ar", tmp_path, drp), "benign": result("benign", tmp_path, []),
               "ablation": result("ablation", tmp_path, []),
               "adaptive": result("adaptive", tmp_path, [(CampaignRun(
                   "local/ld3/msf-output", sc, {"road": "local", "victim": "LD3 default", "threat": "msf-output",
                                                "trials": 4}),
                   {"worst_undetected_m": 0.31, "worst_overall_m": 0.52, "undetected_departures": 0,
                    "replay": f"ld3 run {tmp_path}/adaptive/local/ld3/msf-output/search/best.toml"})])}
    report = write_paper_report(tmp_path, results, quick=True, detector="neural").read_text()
    assert "| LD3 default | 0.31 / 0.52 ([replay](adaptive/local/ld3/msf-output/search/best.toml)) |" in report
    values = load_paper_values()
    for section in values.values():
        assert section["label"] in report
    assert ("| SLR-Low (slr-low) | ld3 | 0.83 / 0.83 | 0.47, 0.08 | 0.50, 0.10 | stop_in_lane | stop_in_lane ×2 "
            "| 2 | `slr-low/ld3-*` |") in report
    assert ("| SLR-Low (slr-low) | ld3-naive-ar | 0.83 / – | 1.69, 0.06 | – | stop_with_lane_straddle | – | 0 "
            "|") in report
    assert "| 4 m/s | LD3 max dev (response) | 0.360, 0.003 | 0.350, 0.050 | 2 |" in report
    assert "| 4 m/s | LD3 response deceleration (m/s²) | < 3 (AR deceleration) | 2.5" in report
    assert "| detection dev (mean, std) | 0.31, 0.07 | 0.35, 0.05 (2 runs) |" in report
    assert "| paper ka-local31 | 0.12, 0.08 | 0.70 / 0.82 / 1.06 | – | – |" in report
    bound = f"{DefenseConfig().b + DefenseConfig().tau:.2f}"  # the run's own (b, τ) in the paper's τ + b + F
    assert f"| ours neural local | 0.000, 0.000 | {bound} / {bound} / {bound} | 0.62 (margin 0 σ) | 0/1 |" in report
    assert "| response max dev (mean, std) | 0.08, 0.08 | 0.05, 0.00 | – |" in report
    assert "| slr-low (sim-table) | 1 | 0 | 0.20 | 0.05 | reach_destination ×1 |" in report
    assert "No fit drive finished" in report
    assert "2 of 2 runs of campaign `chassis`" in report
    assert "| chassis | 2/2 | abcdef012: 1, 012345678-dirty: 1 | `ld3 campaign chassis` |" in report
    assert "| sim-table | 3/3 | unknown: 3 |" in report
    # two known commits mix; the summaries that record none (sim-table's, the search cell's) are not a third tree
    assert "**The runs come from 2 source trees**" in report
    for figure in ("sim_table.png", "chassis_table.png", "trace_replay.png", "drp_ar.png"):
        assert (tmp_path / figure).stat().st_size > 10_000
        assert f"]({figure})" in report


TINY = (
    paper.Experiment("sim-table", "slr-low/ld3-start6"),
    paper.Experiment("chassis", "2mps/ld3-rep0"),
    paper.Experiment("fusionripper-ld3", "local@101-seed1-start8"),
    paper.Experiment("fusionripper-grid", "local-d1-f1.5-drive0"),
    paper.Experiment("roc", "local-fit-seed100,local-benign-seed0,local-fr-d1-f1.5-start8"),
    paper.Experiment("stealthy", "oracle/local-*-seed1"),
    paper.Experiment("drp-ar", "drp-trace/local-start10-seed1"),
    paper.Experiment("benign", "slr-seed0"),
    paper.Experiment("ablation", "paper/trace/urban-straight@101-seed1-start12"),
)


@pytest.mark.slow
def test_ld3_paper_end_to_end_on_a_tiny_selection(chassis_registered, monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(paper, "EXPERIMENTS", TINY)
    argv = ["paper", "--quick", "--out", str(tmp_path), "--workers", "1", "--detector", "oracle"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("ld3 paper (quick): 11 runs to do")
    report = (tmp_path / "report.md").read_text()
    assert "11 of 11 runs done" in report
    assert "1 of 1 runs of campaign `chassis`" in report and "| 2 m/s | LD3 stop dev | 0.010, 0.001 |" in report
    assert "![ROC](roc/roc.png)" in report and (tmp_path / "roc" / "roc.png").is_file()
    for name in (e.campaign for e in TINY):
        assert (tmp_path / name / "report.md").is_file()
    assert main(argv) == 0  # resumed: nothing left to run
    assert capsys.readouterr().out.startswith("ld3 paper (quick): 0 runs to do")
