"""The stealthy-attack bound (`ld3 campaign stealthy`, paper Table "stealthy_detection") in closed loop.

The paper bounds a white-box attacker's undetected deviation by τ + b + F, F the LD fluctuation it manages to
catch (0, μ or μ + 3σ of the LD error). Here the stealthy attacker (testbed.attacks.stealthy) runs against
LD3's real CUSUM with each lane detector; it knows that detector's LD noise std σ (`LD_NOISE_STD`) and keeps a
margin of k σ for k in `MARGINS_SIGMA` (k = 0: it ignores the noise and rides at b; k = 3: it keeps clear of
it). The table measures each detector's LD fluctuation (μ, σ of |D_LD − D_phys| over the detections before
the attack), gives the paper's bound from it, and what the attacker reached in the loop without an alarm.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from testbed.defense.config import DefenseConfig
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.report.summary_stats import fmt_mean_sd, undetected_dev
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary

LD_NOISE_STD: dict[str, dict[str, float]] = {
    "oracle": {"local": 0.0, "highway": 0.0},
    "classical": {"local": 0.127, "highway": 0.081},
    "neural": {"local": 0.013, "highway": 0.023},
}
"""σ of each lane detector's lateral error D_LD − D_phys (m) per track, measured on 25-s benign LD3 drives
(docs/decisions.md): what the white-box attacker is told. A detector without noise gets the margin 0 only."""
MARGINS_SIGMA = (0.0, 1.0, 3.0)
STEALTHY_TRACKS = {"local": 12.0, "highway": 27.0}
SEEDS = (1, 2, 3)
ATTACK_START_S = 10.0
DURATION_S = 40.0


def stealthy_runs(detector: str) -> list[CampaignRun]:
    """Every detector of `LD_NOISE_STD` × track × margin × noise seed, LD3 with its default CUSUM (b, τ)."""
    runs = []
    for det, sigmas in LD_NOISE_STD.items():
        for track, speed in STEALTHY_TRACKS.items():
            sigma = sigmas[track]
            base = load_scenario(track).with_overrides(speed=speed, duration=DURATION_S, detector=det,
                                                       localization="msf", defense="ld3", name=f"stealthy-{track}")
            for k in MARGINS_SIGMA if sigma > 0 else MARGINS_SIGMA[:1]:
                attack = {"kind": "stealthy", "start": ATTACK_START_S, "margin": round(k * sigma, 4),
                          "ld_std": sigma}
                for seed in SEEDS:
                    runs.append(CampaignRun(f"{det}/{track}-margin{k:g}sigma-seed{seed}",
                                            base.with_overrides(seed=seed, attack=attack),
                                            {"detector": det, "track": track, "margin_sigma": k, "seed": seed}))
    return runs


def ld_fluctuation(run_dir: Path, before: float) -> np.ndarray:
    """|D_LD − D_phys| at each fresh lane detection before time `before` (m)."""
    cols = read_trajectory(run_dir, ("t", "phys_dev", "ld_dev", "ld_fresh"))
    keep = (cols["t"] < before) & (cols["ld_fresh"] == 1) & np.isfinite(cols["ld_dev"])
    return np.abs(cols["ld_dev"][keep] - cols["phys_dev"][keep])


def fluctuation_stats(out: Path, runs: list[CampaignRun]) -> tuple[float, float] | None:
    """(μ, σ) of the LD fluctuation pooled over the runs' benign stretches, None without detections."""
    samples = [ld_fluctuation(out / r.run_id, r.tags.get("start", ATTACK_START_S)) for r in runs]
    pooled = np.concatenate(samples) if samples else np.empty(0)
    return (float(pooled.mean()), float(pooled.std())) if pooled.size else None


def paper_bound(mu: float, sigma: float, config: DefenseConfig) -> tuple[float, float, float]:
    """The paper's undetected maximum τ + b + F for F = 0, μ and μ + 3σ, with the CUSUM (b, τ) of `config`."""
    base = config.tau + config.b
    return base, base + mu, base + mu + 3.0 * sigma


def run_bound(mu: float, sigma: float, run: CampaignRun) -> tuple[float, float, float]:
    """`paper_bound` with the CUSUM (b, τ) the run's LD3 used."""
    return paper_bound(mu, sigma, DefenseConfig.from_dict(run.scenario.defense_params))


def stealthy_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["LD fluctuation = |D_LD − D_phys| before the attack, (μ, σ) in m. Bound = the paper's τ + b + F for "
             "F = 0 / μ / μ + 3σ. Reached = max |physical D| without an alarm (before detection, or the whole run), "
             "(mean, std) over the runs.", "",
             "| detector | track | told σ (m) | LD fluctuation μ, σ (m) | bound 0 / μ / μ+3σ (m) | margin | runs "
             "| detected | reached (m) | consequences |", "|---|---|---|---|---|---|---|---|---|---|"]
    for det in LD_NOISE_STD:
        for track in STEALTHY_TRACKS:
            cell = [(r, s) for r, s in done if r.tags["detector"] == det and r.tags["track"] == track]
            if not cell:
                continue
            stats = fluctuation_stats(out, [r for r, _ in cell])
            fluct = "–" if stats is None else f"{stats[0]:.3f}, {stats[1]:.3f}"
            bound = "–" if stats is None else " / ".join(f"{v:.2f}" for v in run_bound(*stats, cell[0][0]))
            for k in MARGINS_SIGMA:
                sums = [s for r, s in cell if r.tags["margin_sigma"] == k]
                if not sums:
                    continue
                lines.append(f"| {det} | {track} | {LD_NOISE_STD[det][track]:.3f} | {fluct} | {bound} | {k:g} σ "
                             f"| {len(sums)} | {sum(bool(s.detected) for s in sums)}/{len(sums)} "
                             f"| {fmt_mean_sd(undetected_dev(s) for s in sums)} "
                             f"| {', '.join(sorted({s.consequence for s in sums}))} |")
    return "\n".join(lines)
