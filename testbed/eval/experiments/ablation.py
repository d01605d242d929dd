"""The LD3 attack-response ablation (`ld3 campaign ablation`): response variants × attacks × roads.

Variants are `[defense]` overrides of LD3, the paper mode first. Attacks: FusionRipper in closed loop
(d = 1.0, f = 1.5), the default trace injection, an LD deviation trace (drp-trace), an LD trace that also
bends the lines (drp-bend), and the stealthy attacker. Roads: held-out seeds of local, highway and
urban-straight (never the canonical layouts the defaults were tuned on), several noise seeds and start
times, with the oracle lane detector so that the response, not the detector, is what differs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from testbed.defense.config import PAPER_MODE, DefenseConfig
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary

_W20 = {"window": 20, "p_source": "constant", "r_power": 1.0}
VARIANTS: dict[str, dict[str, Any]] = {
    "paper": dict(PAPER_MODE),
    "heading-lane": {**_W20, "heading": "lane"},
    "heading-ld": {**_W20, "heading": "ld", "heading_clamp": 0.05},
    "heading-ld-clamp0.03": {**_W20, "heading": "ld", "heading_clamp": 0.03},
    "heading-ld-clamp0.02": {**_W20, "heading": "ld", "heading_clamp": 0.02},
    "heading-fused": {**_W20, "heading": "fused", "heading_clamp": 0.05},
    "heading-ld-window5": {**_W20, "heading": "ld", "heading_clamp": 0.05, "window": 5},
    "heading-ld-p-reported": {**_W20, "heading": "ld", "heading_clamp": 0.05, "p_source": "reported"},
    "heading-ld-r-power2": {**_W20, "heading": "ld", "heading_clamp": 0.05, "r_power": 2.0},
    "heading-ld-clamp0.02-window5": {**_W20, "heading": "ld", "heading_clamp": 0.02, "window": 5},
    "heading-fused-window5": {**_W20, "heading": "fused", "heading_clamp": 0.05, "window": 5},
    "heading-fused-clamp0.02-window5": {**_W20, "heading": "fused", "heading_clamp": 0.02, "window": 5},
}
"""LD3 response variants, each a complete set of the response options ("paper" = the paper mode), so that a
variant means the same whatever the defaults are; the table marks the one that equals the defaults."""

ATTACKS: dict[str, dict[str, Any]] = {
    "fusionripper": {"kind": "fusionripper", "d": 1.0, "f": 1.5},
    "trace": {"kind": "trace", "trace": "default"},
    "drp-trace": {"kind": "drp-trace"},
    "drp-bend": {"kind": "drp-bend"},
    "stealthy": {"kind": "stealthy"},
}
ROADS = {"local": 12.0, "highway": 27.0, "urban-straight": 12.0}
TRACK_SEEDS = (101,)
"""Held-out layouts: the defaults were chosen on the canonical seed-0 layouts."""
NOISE_SEEDS = (1, 2, 3)
STARTS = (12.0, 18.0)


def ablation_runs(detector: str) -> list[CampaignRun]:
    """Every variant on every attack, road, track seed, noise seed and start time, with the oracle detector."""
    runs = []
    for variant, overrides in VARIANTS.items():
        for attack, spec in ATTACKS.items():
            for road, speed in ROADS.items():
                for track_seed in TRACK_SEEDS:
                    base = load_scenario(road).with_overrides(
                        track=f"{road}@{track_seed}", speed=speed, duration=60.0, detector="oracle",
                        localization="msf", defense="ld3", name=f"ablation-{variant}")
                    for seed in NOISE_SEEDS:
                        for start in STARTS:
                            sc = base.with_overrides(seed=seed, attack={**spec, "start": start},
                                                     defense_params=dict(overrides))
                            runs.append(CampaignRun(
                                f"{variant}/{attack}/{road}@{track_seed}-seed{seed}-start{start:g}", sc,
                                {"variant": variant, "attack": attack, "track": road, "track_seed": track_seed,
                                 "start": start}))
    return runs


def is_default(overrides: dict[str, Any]) -> bool:
    """True when the variant's options resolve to the default `[defense]` table."""
    return DefenseConfig.from_dict(overrides) == DefenseConfig()


def _mean_sd(values: list[float | None]) -> str:
    arr = np.array([v for v in values if v is not None], dtype=float)
    return "–" if arr.size == 0 else f"{arr.mean():.2f} ± {arr.std():.2f}"


IN_LANE = ("stop_in_lane", "reach_destination")


def _save_ablation_plot(path: Path, done: list[tuple[CampaignRun, RunSummary]]) -> None:
    """One panel per attack: each variant's AR max |D| over its runs (dots, mean bar), out-of-lane runs in red."""
    fig = Figure(figsize=(3.2 * len(ATTACKS), 0.35 * len(VARIANTS) + 1.5))
    axes = fig.subplots(1, len(ATTACKS), sharey=True)
    for ax, attack in zip(axes, ATTACKS, strict=True):
        for i, variant in enumerate(VARIANTS):
            sums = [s for run, s in done if run.tags["variant"] == variant and run.tags["attack"] == attack]
            devs = [(s.ar_max_dev_m if s.ar_max_dev_m is not None else s.max_abs_dev_m or 0.0,
                     s.consequence in IN_LANE) for s in sums]
            if not devs:
                continue
            ax.barh(i, np.mean([d for d, _ in devs]), color="0.85")
            ax.scatter([d for d, ok in devs], [i] * len(devs), s=10,
                       c=["tab:blue" if ok else "tab:red" for _, ok in devs], zorder=3)
        ax.set_title(attack, fontsize=9)
        ax.set_xlabel("AR max |D| (m)")
        ax.grid(axis="x", alpha=0.3)
    axes[0].set_yticks(range(len(VARIANTS)), list(VARIANTS), fontsize=8)
    axes[0].invert_yaxis()
    fig.suptitle("LD3 response ablation: red = the run left its lane (max |D| where no response ran)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def ablation_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    """Per attack, one row per variant (paper mode first): in-lane rate, detection, deviations; and
    `ablation.png`."""
    _save_ablation_plot(out / "ablation.png", done)
    lines = ["In lane = the run ended without leaving the lane: reached the end or stopped with |D| below the lane "
             "straddle deviation. Deviations are |physical D| in m (mean ± sd over runs). Figure: ablation.png.", ""]
    for attack in ATTACKS:
        lines += [f"**{attack}**", "", "| variant | runs | in lane | detected | max dev | detection dev "
                  "| AR max dev | stop dev | consequences |", "|---|---|---|---|---|---|---|---|---|"]
        for variant in VARIANTS:
            sums = [s for run, s in done if run.tags["variant"] == variant and run.tags["attack"] == attack]
            if not sums:
                continue
            in_lane = sum(s.consequence in IN_LANE for s in sums)
            label = f"{variant} (default)" if is_default(VARIANTS[variant]) else variant
            cons: dict[str, int] = {}
            for s in sums:
                cons[s.consequence] = cons.get(s.consequence, 0) + 1
            stop = [abs(s.ar_stop_dev_m) if s.ar_stop_dev_m is not None else None for s in sums]
            lines.append(f"| {label} | {len(sums)} | {in_lane}/{len(sums)} ({100 * in_lane / len(sums):.0f}%) "
                         f"| {sum(bool(s.detected) for s in sums)}/{len(sums)} "
                         f"| {_mean_sd([s.max_abs_dev_m for s in sums])} "
                         f"| {_mean_sd([s.detection_dev_m for s in sums])} "
                         f"| {_mean_sd([s.ar_max_dev_m for s in sums])} | {_mean_sd(stop)} "
                         f"| {', '.join(f'{k} ×{v}' for k, v in sorted(cons.items()))} |")
        lines.append("")
    return "\n".join(lines)
