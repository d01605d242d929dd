"""The simulator table (`ld3 campaign sim-table`, paper Table "sim_results"): the default trace injection
against LD3, LD3-NaiveAR and no defense on each of the paper's four simulator scenarios, plus benign LD3.

The paper's scenarios map to the presets: SLR-Low and SLR-High to `slr` at 10 and 20 m/s, SF-Straight to
`urban-straight` (12 m/s), SF-Curvy to `urban-curvy` (10 m/s). Each attacked setting runs at every start
time of `SIM_STARTS` (the paper: 10 randomised start times); benign LD3 runs once per seed of `BENIGN_SEEDS`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.report.summary_stats import consequences, fmt_mean_sd
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary

SIM_SCENARIOS: dict[str, tuple[str, float]] = {
    "slr-low": ("slr", 10.0),
    "slr-high": ("slr", 20.0),
    "urban-straight": ("urban-straight", 12.0),
    "urban-curvy": ("urban-curvy", 10.0),
}
"""Our scenario key -> (preset, speed in m/s)."""
SIM_DEFENSES = ("ld3", "ld3-naive-ar", "none")
SIM_STARTS = tuple(float(s) for s in range(6, 16))
BENIGN_SEEDS = tuple(range(10))
ATTACKED_AFTER_S = 20.0
"""Simulated time after the attack start: the trace reaches 4 m after 12 s, the slowest stop takes 5 s."""
BENIGN_DURATION_S = 30.0
SETTINGS = (*SIM_DEFENSES, "benign")


def sim_table_runs(detector: str) -> list[CampaignRun]:
    """Per scenario: every defense × start time under `trace:default`, then benign LD3 per seed."""
    runs = []
    for key, (preset, speed) in SIM_SCENARIOS.items():
        base = load_scenario(preset).with_overrides(speed=speed, detector=detector, localization="msf",
                                                    name=f"sim-{key}")
        for defense in SIM_DEFENSES:
            for start in SIM_STARTS:
                sc = base.with_overrides(defense=defense, duration=start + ATTACKED_AFTER_S,
                                         attack={"kind": "trace", "trace": "default", "start": start})
                runs.append(CampaignRun(f"{key}/{defense}-start{start:g}", sc,
                                        {"scenario": key, "setting": defense, "start": start}))
        for seed in BENIGN_SEEDS:
            sc = base.with_overrides(defense="ld3", seed=seed, duration=BENIGN_DURATION_S)
            runs.append(CampaignRun(f"{key}/benign-seed{seed}", sc, {"scenario": key, "setting": "benign",
                                                                     "seed": seed}))
    return runs


def group_by_setting(done: list[tuple[CampaignRun, RunSummary]]) -> dict[tuple[str, str], list[RunSummary]]:
    """{(scenario, setting): summaries} in the order of `SIM_SCENARIOS` and `SETTINGS`."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {(k, s): [] for k in SIM_SCENARIOS for s in SETTINGS}
    for run, summary in done:
        groups[(run.tags["scenario"], run.tags["setting"])].append(summary)
    return {key: sums for key, sums in groups.items() if sums}


def sim_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["Max dev = max |physical D| over the whole run, (mean, std) in m; benign = LD3 without attack.", "",
             "| scenario | setting | runs | lane straddle dev (m) | max dev (m) | detected | consequences |",
             "|---|---|---|---|---|---|---|"]
    for (key, setting), sums in group_by_setting(done).items():
        straddle = sums[0].lane_straddle_dev_m
        lines.append(f"| {key} | {setting} | {len(sums)} | {straddle:.2f} "
                     f"| {fmt_mean_sd(s.max_abs_dev_m for s in sums)} "
                     f"| {sum(bool(s.detected) for s in sums)}/{len(sums)} | {consequences(sums)} |")
    return "\n".join(lines)
