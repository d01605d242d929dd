"""DRP during the attack response (`ld3 campaign drp-ar`, paper Fig. "ld_attack_devs"), with a camera
lane detector.

An LD-side attack can move the car only through LD3's response: it must first raise the alarm, then pull
the fused pose. Two forms: `drp-trace`, the paper's DRP deviation trace (0.7 m, the detection deviation the
paper starts it from) injected into the detector's output, on local, highway and urban-straight; and
`drp-patch`, a dark patch painted on urban-straight that the camera sees and the detector reacts to on its
own (a patch that raises no alarm cannot steer the car, which still drives on the MSF).
"""

from __future__ import annotations

from pathlib import Path

from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.report.summary_stats import abs_or_none, consequences, fmt_mean_sd
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary

TRACE_ROADS = {"local": 12.0, "highway": 27.0, "urban-straight": 12.0}
TRACE_STARTS = (10.0, 15.0)
PATCH_ROAD, PATCH_SPEED = "urban-straight", 12.0
PATCH = {"kind": "drp-patch", "offset": -1.0, "width": 2.0, "length": 30.0, "darkness": 0.7, "angle": -0.05}
"""Over the right line, whose edge the neural detector follows (the `ld3 patch-figure` patch)."""
PATCH_AT = (62.0, 140.0)
SEEDS = (1, 2)
AFTER_S = 15.0
"""Simulated time after the attack starts (or the patch is reached)."""


def drp_runs(detector: str) -> list[CampaignRun]:
    """drp-trace per road × start × seed, then drp-patch per position × seed; LD3 on the MSF."""
    runs = []
    for road, speed in TRACE_ROADS.items():
        base = load_scenario(road).with_overrides(speed=speed, detector=detector, localization="msf",
                                                  defense="ld3", name=f"drp-trace-{road}")
        for start in TRACE_STARTS:
            for seed in SEEDS:
                sc = base.with_overrides(seed=seed, duration=start + AFTER_S,
                                         attack={"kind": "drp-trace", "start": start})
                runs.append(CampaignRun(f"drp-trace/{road}-start{start:g}-seed{seed}", sc,
                                        {"attack": "drp-trace", "road": road, "start": start, "seed": seed}))
    base = load_scenario(PATCH_ROAD).with_overrides(speed=PATCH_SPEED, detector=detector, localization="msf",
                                                    defense="ld3", name="drp-patch")
    for at in PATCH_AT:
        reach = (at - base.start_s) / PATCH_SPEED
        for seed in SEEDS:
            sc = base.with_overrides(seed=seed, duration=reach + AFTER_S, attack={**PATCH, "at": at})
            runs.append(CampaignRun(f"drp-patch/{PATCH_ROAD}-at{at:g}-seed{seed}", sc,
                                    {"attack": "drp-patch", "road": PATCH_ROAD, "at": at, "seed": seed}))
    return runs


def drp_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["AR max / stop dev = max |physical D| during the response and |D| at the stop, (mean, std) in m over "
             "the runs that raised the alarm; max dev = over the whole run, all runs.", "",
             "| attack | road | runs | alarm raised | AR max dev (m) | stop dev (m) | max dev (m) "
             "| lane straddle dev (m) | consequences |", "|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str], list[RunSummary]] = {}
    for run, summary in done:
        groups.setdefault((run.tags["attack"], run.tags["road"]), []).append(summary)
    for (attack, road), sums in groups.items():
        alarmed = [s for s in sums if s.detected]
        lines.append(f"| {attack} | {road} | {len(sums)} | {len(alarmed)}/{len(sums)} "
                     f"| {fmt_mean_sd(s.ar_max_dev_m for s in alarmed)} "
                     f"| {fmt_mean_sd(abs_or_none(s.ar_stop_dev_m) for s in alarmed)} "
                     f"| {fmt_mean_sd(s.max_abs_dev_m for s in sums)} | {sums[0].lane_straddle_dev_m:.2f} "
                     f"| {consequences(sums)} |")
    return "\n".join(lines)
