"""The named campaigns that reproduce the paper's experiments (`ld3 campaign NAME`), each a list of
runs and a table of what the paper reports for it.
"""

from __future__ import annotations

import dataclasses
import fnmatch
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from testbed.errors import UserError
from testbed.eval.campaign.driver import (
    CAMPAIGN_BACKENDS,
    CampaignRun,
    RunExecutor,
    run_and_write,
    run_and_write_data,
    run_campaign,
)
from testbed.eval.experiments.ablation import ablation_runs, ablation_table
from testbed.eval.experiments.adaptive import adaptive_runs, adaptive_table, run_cells, with_budget
from testbed.eval.experiments.cusum_fit import cusum_check_runs, cusum_fit_runs, cusum_fit_table
from testbed.eval.experiments.drp_response import drp_runs, drp_table
from testbed.eval.experiments.map_drives import map_runs, map_table
from testbed.eval.experiments.roc import record_detection_run, roc_runs, roc_table
from testbed.eval.experiments.sim_table import sim_table, sim_table_runs
from testbed.eval.experiments.stealthy_bound import stealthy_runs, stealthy_table
from testbed.eval.report.summary_stats import consequences
from testbed.eval.run.consequence import ATTACK_GOAL_M, attack_succeeded
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import add_attacks, apply_settings, load_scenario
from testbed.eval.run.summary import RunSummary
from testbed.registry import Capability, Registry


@dataclass(frozen=True)
class CampaignSpec:
    """A named campaign (an entry of the campaign registry): what it reproduces, its runs for a lane
    detector, how each is executed, and its report table."""

    name: str
    help: str
    build: Callable[[str], list[CampaignRun]]
    table: Callable[[list[tuple[CampaignRun, Any]], Path], str]
    """The report table from (run, its `RunSummary`), or for a campaign of searches (cell, the cell's summary)."""
    execute: RunExecutor = run_and_write
    needs: frozenset[Capability] = frozenset()
    searches: Callable[..., list[tuple[CampaignRun, dict[str, Any]]]] | None = None
    """For a campaign of attack searches: runs each of its runs as a search cell
    (`testbed.eval.experiments.adaptive`) in place of `run_campaign`; its runs' `trials` tag is the budget of each
    search."""
    on_maps: Callable[[str, Sequence[str]], list[CampaignRun]] | None = None
    """For a campaign over OpenDRIVE files: its runs for a lane detector and the `--maps` given (which it needs;
    `build` then gives none)."""
    figures_later: bool = False
    """Whether its runs leave their figures (birdseye.png, ar_fusion.png) to `ld3 figures` unless `--figures-now`
    is given: a campaign of many runs whose report reads only their summaries. Its help says so (LATER_NOTE);
    only for runs that write the standard outputs."""


LATER_NOTE = "; per-run figures left to `ld3 figures`"
"""Ends the help of a campaign whose runs leave their figures for later by default (`CampaignSpec.figures_later`)."""


def _fmt(v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


def _span(values: list[float]) -> str:
    """'a' when every value rounds alike, else 'min–max' (the lane straddle deviation over road layouts)."""
    lo, hi = min(values), max(values)
    return f"{lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}–{hi:.2f}"


def _margin(sums: list[RunSummary]) -> str:
    """Smallest lane straddle deviation − max |D| over the runs that stayed in lane ('–' if none did)."""
    margins = [s.lane_straddle_dev_m - (s.max_abs_dev_m or 0.0) for s in sums
               if s.consequence in ("stop_in_lane", "reach_destination")]
    return f"{min(margins):.2f}" if margins else "–"


def _stats(values: list[float]) -> str:
    arr = np.array([v for v in values if v is not None], dtype=float)
    if arr.size == 0:
        return "–"
    return f"{arr.mean():.2f} ± {arr.std():.2f} (max {arr.max():.2f})"


# ---- foundation: lane keeping with the true pose, and on the MSF ---------------------------------------
LANE_KEEPING = (("slr", 10.0, 60.0), ("slr", 27.0, 60.0), ("urban-straight", 12.0, 60.0),
                ("urban-curvy", 10.0, 120.0), ("highway", 27.0, 90.0))
LANE_KEEPING_LIMIT_M = {"slr": 0.10, "urban-straight": 0.10, "urban-curvy": 0.25, "highway": 0.15}
"""The largest benign |physical deviation| lane keeping with the true pose may reach, per track (m)."""
MSF_ALLOWANCE_M = 0.05  # what steering on the MSF may add to the true-pose limit
MSF_SEEDS = range(5)


def lane_keeping_runs(detector: str) -> list[CampaignRun]:
    runs = [CampaignRun(f"{track}-{speed:g}", load_scenario(track).with_overrides(
        speed=speed, duration=duration, detector="none", localization="truth", name=f"{track}-{speed:g}"),
        {"track": track, "speed": speed}) for track, speed, duration in LANE_KEEPING]
    stop = load_scenario("highway").with_overrides(speed=27.0, duration=60.0, detector="none", stop_at=40.0,
                                                   stop_decel=4.0, name="highway-stop")
    runs.append(CampaignRun("highway-27-stop", stop, {"track": "highway", "speed": 27.0}))
    return runs


def lane_keeping_msf_runs(detector: str) -> list[CampaignRun]:
    return [CampaignRun(f"{track}-{speed:g}-seed{seed}", load_scenario(track).with_overrides(
        speed=speed, duration=duration, detector="none", localization="msf", seed=seed,
        name=f"{track}-{speed:g}-msf"), {"track": track, "speed": speed, "seed": seed})
        for track, speed, duration in LANE_KEEPING for seed in MSF_SEEDS]


def cruise_speed_error(run_dir: Path, target: float, until: float | None) -> float | None:
    """Steady-state speed error: max |speed − target| from when the car first came within 0.05 m/s of the
    target until `until` (a planned stop) or the end."""
    cols = read_trajectory(run_dir, ("t", "speed"))
    t, speeds = cols["t"], cols["speed"]
    window = speeds[t < until] if until is not None else speeds
    reached = np.flatnonzero(np.abs(window - target) <= 0.05)
    if reached.size == 0:
        return None
    return float(np.max(np.abs(window[reached[0]:] - target)))


def msf_lateral_error(run_dir: Path) -> np.ndarray:
    """Lateral MSF error along a run, msf_dev − phys_dev (m, lane frame)."""
    cols = read_trajectory(run_dir, ("msf_dev", "phys_dev"))
    err = cols["msf_dev"] - cols["phys_dev"]
    return err[np.isfinite(err)]


MSF_TARGET_RMS_M, MSF_TARGET_MAX_M = 0.10, 0.30
"""The benign MSF lateral error (RMS, max; m) allowed on every preset."""


def msf_error_cells(run_dirs: list[Path]) -> str:
    """Table cells 'worst RMS | max' of the MSF lateral error over runs."""
    errs = [msf_lateral_error(d) for d in run_dirs]
    rms = max(float(np.sqrt(np.mean(e**2))) for e in errs)
    return f"{rms:.3f} (worst run) | {max(float(np.abs(e).max()) for e in errs):.3f}"


def lane_keeping_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["| run | max abs dev (m) | limit (m) | final dev (m) | cruise speed error max (m/s) | consequence "
             "| stop time (s) |", "|---|---|---|---|---|---|---|"]
    for run, s in done:
        err = cruise_speed_error(out / run.run_id, run.tags["speed"], run.scenario.stop_at)
        lines.append(f"| {run.run_id} | {_fmt(s.max_abs_dev_m)} | {LANE_KEEPING_LIMIT_M[run.tags['track']]:.2f} "
                     f"| {_fmt(s.final_dev_m)} | {_fmt(err)} | {s.consequence} "
                     f"| {_fmt(s.stop_time_s)} |")
    return "\n".join(lines)


def lane_keeping_msf_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = [f"Steering on the MSF; limit = the true-pose limit + {MSF_ALLOWANCE_M:.2f} m. One row per track and "
             f"speed over seeds {MSF_SEEDS.start}–{MSF_SEEDS.stop - 1}.", "",
             "| run | seeds | max abs dev per seed (m) | worst (m) | limit (m) | within | MSF lateral error RMS (m) "
             "| MSF lateral error max (m) | consequences |", "|---|---|---|---|---|---|---|---|---|"]
    groups: dict[str, list[tuple[CampaignRun, RunSummary]]] = {}
    for run, s in done:
        groups.setdefault(f"{run.tags['track']}-{run.tags['speed']:g}", []).append((run, s))
    for key, items in groups.items():
        limit = LANE_KEEPING_LIMIT_M[items[0][0].tags["track"]] + MSF_ALLOWANCE_M
        devs = [s.max_abs_dev_m for _, s in items]
        worst = max(devs)
        within = sum(d <= limit for d in devs)
        cons = sorted({s.consequence for _, s in items})
        lines.append(f"| {key} | {len(items)} | {' / '.join(f'{d:.3f}' for d in devs)} | {worst:.3f} | {limit:.2f} "
                     f"| {within}/{len(items)} | {msf_error_cells([out / run.run_id for run, _ in items])} "
                     f"| {', '.join(cons)} |")
    return "\n".join(lines)


# ---- LD3 in the closed loop (paper Table 4) ------------------------------------------------------------
TABLE4_STARTS = (6.0, 8.0, 10.0, 12.0, 14.0)
DEFENSES = ("none", "ld3-naive-ar", "ld3")


def table4_runs(detector: str) -> list[CampaignRun]:
    base = load_scenario("urban-straight").with_overrides(speed=12.0, duration=40.0, detector=detector,
                                                          localization="msf")
    return [CampaignRun(f"{d}-start{start:g}", base.with_overrides(
        defense=d, attack={"kind": "trace", "trace": "default", "start": start}, name=f"table4-{d}"),
        {"defense": d, "start": start}) for d in DEFENSES for start in TABLE4_STARTS]


def defense_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["Margin = lane straddle deviation − max |D|, the smallest over the row's runs that stayed in lane.",
             "", "| defense | runs | lane straddle dev (m) | max dev (m) | margin (m) | consequences | detected "
             "| detection dev (m) | AR max dev (m) | stop dev (m) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    by_def: dict[str, list[RunSummary]] = {}
    for run, s in done:
        by_def.setdefault(f"{run.tags.get('track', '')} {s.defense}".strip(), []).append(s)
    for key, sums in by_def.items():
        cons: dict[str, int] = {}
        for s in sums:
            cons[s.consequence] = cons.get(s.consequence, 0) + 1
        lines.append(
            f"| {key} | {len(sums)} | {_span([s.lane_straddle_dev_m for s in sums])} "
            f"| {_stats([s.max_abs_dev_m for s in sums])} "
            f"| {_margin(sums)} "
            f"| {', '.join(f'{k} ×{v}' for k, v in sorted(cons.items()))} "
            f"| {sum(bool(s.detected) for s in sums)}/{len(sums)} "
            f"| {_stats([s.detection_dev_m for s in sums])} | {_stats([s.ar_max_dev_m for s in sums])} "
            f"| {_stats([abs(s.ar_stop_dev_m) if s.ar_stop_dev_m is not None else None for s in sums])} |")
    return "\n".join(lines)


# ---- FusionRipper through the MSF, with LD3 --------------------------------------------------------------
FR_TRACKS = {"local": 12.0, "highway": 27.0}
FR_BEST = {"d": 1.0, "f": 1.5}
FR_LD3_TRACK_SEEDS = (101, 202, 303)
"""Held-out road layouts (LD3's response defaults were chosen on the canonical seed-0 layouts)."""
FR_LD3_NOISE_SEEDS = (1, 2, 3)
FR_LD3_STARTS = (8.0, 12.5, 17.0, 21.5, 26.0)


def fusionripper_ld3_runs(detector: str) -> list[CampaignRun]:
    """Held-out track seeds × noise seeds × start times per track, LD3 with its default response."""
    runs = []
    for track, speed in FR_TRACKS.items():
        for track_seed in FR_LD3_TRACK_SEEDS:
            base = load_scenario(track).with_overrides(track=f"{track}@{track_seed}", speed=speed, duration=60.0,
                                                       detector=detector, localization="msf", defense="ld3")
            for seed in FR_LD3_NOISE_SEEDS:
                for start in FR_LD3_STARTS:
                    runs.append(CampaignRun(f"{track}@{track_seed}-seed{seed}-start{start:g}", base.with_overrides(
                        seed=seed, attack={"kind": "fusionripper", **FR_BEST, "start": start}, name=f"fr-{track}"),
                        {"track": track, "track_seed": track_seed, "seed": seed, "start": start}))
    return runs


# ---- FusionRipper into oncoming traffic ------------------------------------------------------------------
TWO_WAY_SPEED = 13.0
TWO_WAY_STARTS = (8.0, 14.0, 20.0)
TWO_WAY_TRAFFIC = {"vehicles": 8, "speed": TWO_WAY_SPEED + 2.0, "gap": 35.0}
"""Four cars each way; those ahead in the ego lane drive faster than the ego car, which does not follow cars."""


def fusionripper_two_way_runs(detector: str) -> list[CampaignRun]:
    """FusionRipper spoofing right, so lane centring steers the car left over the centre line into the oncoming
    stream: held-out two-way layouts × noise seeds × start times, without defense and with default LD3."""
    runs = []
    for defense in ("none", "ld3"):
        for track_seed in FR_LD3_TRACK_SEEDS:
            base = load_scenario("two-way").with_overrides(
                track=f"two-way@{track_seed}", speed=TWO_WAY_SPEED, duration=45.0, localization="msf",
                defense=defense, detector=detector if defense != "none" else "none", traffic=TWO_WAY_TRAFFIC)
            for seed in FR_LD3_NOISE_SEEDS[:2]:
                for start in TWO_WAY_STARTS:
                    runs.append(CampaignRun(f"{defense}-two-way@{track_seed}-seed{seed}-start{start:g}",
                                            base.with_overrides(seed=seed, name=f"fr-two-way-{defense}", attack={
                                                "kind": "fusionripper", **FR_BEST, "start": start,
                                                "direction": "right"}),
                                            {"track": "two-way", "track_seed": track_seed, "seed": seed,
                                             "start": start}))
    return runs


# ---- benign false alarms ---------------------------------------------------------------------------------
BENIGN_PRESETS = ("slr", "urban-straight", "urban-curvy", "highway", "local", "parking-lot")


def benign_runs(detector: str) -> list[CampaignRun]:
    return [CampaignRun(f"{p}-seed{seed}", load_scenario(p).with_overrides(
        seed=seed, detector=detector, localization="msf", defense="ld3", duration=min(60.0, load_scenario(p).duration),
        name=f"benign-{p}"), {"track": p, "seed": seed}) for p in BENIGN_PRESETS for seed in range(5)]


def benign_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = [f"MSF lateral error target: RMS ≤ {MSF_TARGET_RMS_M:.2f} m, max ≤ {MSF_TARGET_MAX_M:.2f} m.", "",
             "| track | runs | false alarms | max abs dev (m) | MSF lateral error RMS (m) | MSF lateral error max (m) "
             "| consequences |", "|---|---|---|---|---|---|---|"]
    by_track: dict[str, list[tuple[CampaignRun, RunSummary]]] = {}
    for run, s in done:
        by_track.setdefault(run.tags["track"], []).append((run, s))
    for track, items in by_track.items():
        sums = [s for _, s in items]
        lines.append(f"| {track} | {len(sums)} | {sum(bool(s.detected) for s in sums)} "
                     f"| {_stats([s.max_abs_dev_m for s in sums])} "
                     f"| {msf_error_cells([out / run.run_id for run, _ in items])} "
                     f"| {', '.join(sorted({s.consequence for s in sums}))} |")
    return "\n".join(lines)


# ---- benign false alarms in traffic ----------------------------------------------------------------------
BENIGN_TRAFFIC_PRESETS = (*BENIGN_PRESETS, "two-way")
BENIGN_TRAFFIC_CARS = 6
BENIGN_TRAFFIC_SEEDS = range(3)
BENIGN_TRAFFIC_DURATION_S = 15.0


def benign_traffic_runs(detector: str) -> list[CampaignRun]:
    """Benign default LD3 on the MSF in every benign preset and the two-way road × condition × seed with
    `BENIGN_TRAFFIC_CARS` cars
    (`testbed.perception.lab.traffic_drive`: every car at the ego's speed, started at rest with the ego, a lead car
    close ahead in the ego lane),
    for the preset's duration up to `BENIGN_TRAFFIC_DURATION_S`; a neural detector reads the shipped weights, as
    every run does."""
    from testbed.conditions import CONDITIONS
    from testbed.perception.lab.traffic_drive import traffic_drive
    from tracks.presets import load_track

    runs = []
    for p in BENIGN_TRAFFIC_PRESETS:
        base = load_scenario(p)
        track = load_track(base.track)
        duration = min(BENIGN_TRAFFIC_DURATION_S, base.duration)
        fitted = traffic_drive(track, base.lane if base.lane is not None else track.ego_lane, base.start_s,
                               base.vehicle, base.speed, duration, BENIGN_TRAFFIC_CARS)
        runs += [CampaignRun(f"{p}-{cond}-seed{seed}", base.with_overrides(
            seed=seed, condition=cond, detector=detector, localization="msf", defense="ld3", duration=duration,
            speed=fitted.speed, traffic=fitted.traffic, name=f"benign-traffic-{p}"),
            {"track": p, "condition": cond, "seed": seed}) for cond in CONDITIONS for seed in BENIGN_TRAFFIC_SEEDS]
    return runs


def tracked_ld_error(run_dir: Path) -> np.ndarray:
    """|D_LD − physical D| along a run (m), the ticks with a D_LD."""
    cols = read_trajectory(run_dir, ("ld_dev", "phys_dev"))
    err = np.abs(cols["ld_dev"] - cols["phys_dev"])
    return err[np.isfinite(err)]


def benign_traffic_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    lines = ["Tracked |D_LD error| (the D_LD LD3 read, against the physical D) pooled over the seeds' ticks; "
             "target p99 ≤ 0.20 m. False alarms must be 0.", "",
             "| track | condition | runs | cars | speed (m/s) | false alarms | tracked D_LD err mean (m) "
             "| tracked D_LD err p99 (m) | max abs dev (m) | consequences |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str], list[tuple[CampaignRun, RunSummary]]] = {}
    for run, s in done:
        groups.setdefault((run.tags["track"], run.tags["condition"]), []).append((run, s))
    worst, alarms = 0.0, 0
    for (track, cond), items in groups.items():
        sums = [s for _, s in items]
        err = np.concatenate([tracked_ld_error(out / run.run_id) for run, _ in items])
        p99 = float(np.percentile(err, 99)) if err.size else None
        worst = max(worst, p99 or 0.0)
        detected = sum(bool(s.detected) for s in sums)
        alarms += detected
        sc = items[0][0].scenario
        lines.append(f"| {track} | {cond} | {len(sums)} | {sc.traffic.vehicles} | {sc.speed:.2f} "
                     f"| {detected} | {_fmt(float(err.mean()) if err.size else None)} "
                     f"| {_fmt(p99)} | {_stats([s.max_abs_dev_m for s in sums])} | {consequences(sums)} |")
    lines += ["", f"All: {len(done)} runs, {alarms} false alarms, largest tracked D_LD err p99 {worst:.3f} m."]
    return "\n".join(lines)


# ---- FusionRipper parameter grid without defense (paper Table 2) -----------------------------------------
GRID_D = (0.3, 0.5, 0.7, 1.0)
GRID_F = (1.1, 1.2, 1.3, 1.5)


GRID_TRACK_SEEDS = (0, 101, 202, 303)
GRID_DRIVES = 20
"""Drives per cell: drive k starts at 8 + 1.3 k s, with noise seed k and track seed GRID_TRACK_SEEDS[k % 4]."""


def fr_grid_runs(detector: str) -> list[CampaignRun]:
    """Drive index outermost, so that a campaign stopped part-way has the same drives in every cell; each
    drive varies start time, sensor-noise seed and road layout together."""
    runs = []
    for k in range(GRID_DRIVES):
        start = round(8.0 + 1.3 * k, 1)
        track_seed = GRID_TRACK_SEEDS[k % len(GRID_TRACK_SEEDS)]
        for track, speed in FR_TRACKS.items():
            base = load_scenario(track).with_overrides(track=f"{track}@{track_seed}", speed=speed, duration=50.0,
                                                       seed=k, detector="none", localization="msf", defense="none")
            for d in GRID_D:
                for f in GRID_F:
                    runs.append(CampaignRun(f"{track}-d{d:g}-f{f:g}-drive{k}", base.with_overrides(
                        attack={"kind": "fusionripper", "d": d, "f": f, "start": start}, name=f"grid-{track}"),
                        {"track": track, "d": d, "f": f, "start": start, "seed": k, "track_seed": track_seed}))
    return runs


def _save_grid_heatmap(path: Path, cells: dict[tuple[str, float, float], list[bool]]) -> None:
    """One panel per track: the attack success rate of each d × f cell, annotated with the rate and the
    number of drives (grey where the cell has none)."""
    fig = Figure(figsize=(4.2 * len(FR_TRACKS) + 1.0, 3.8), layout="constrained")
    axes = fig.subplots(1, len(FR_TRACKS), squeeze=False)
    for ax, track in zip(axes[0], FR_TRACKS, strict=True):
        rate = np.full((len(GRID_D), len(GRID_F)), np.nan)
        for i, d in enumerate(GRID_D):
            for j, f in enumerate(GRID_F):
                res = cells.get((track, d, f), [])
                if res:
                    rate[i, j] = 100.0 * np.mean(res)
                label = f"{rate[i, j]:.0f}%\n({len(res)})" if res else "–"
                colour = "white" if res and rate[i, j] < 60.0 else "black"
                ax.text(j, i, label, ha="center", va="center", fontsize=8, color=colour)
        image = ax.imshow(rate, cmap=colormaps["viridis"].with_extremes(bad="0.85"), vmin=0.0,
                          vmax=100.0, origin="lower")
        ax.set_xticks(range(len(GRID_F)), [f"{f:g}" for f in GRID_F])
        ax.set_yticks(range(len(GRID_D)), [f"{d:g}" for d in GRID_D])
        ax.set_xlabel("f")
        ax.set_ylabel("d (m)")
        ax.set_title(f"{track} (goal {ATTACK_GOAL_M[track]} m)", fontsize=9)
    fig.colorbar(image, ax=axes[0].tolist(), label="attack success (%)", shrink=0.8)
    fig.suptitle("FusionRipper without defense: success rate per d × f cell (drives in brackets)", fontsize=9)
    fig.savefig(path, dpi=110)


def fr_grid_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    cells: dict[tuple[str, float, float], list[bool]] = {}
    giveway: dict[tuple[str, float, float], list[float]] = {}
    for run, s in done:
        key = (run.tags["track"], run.tags["d"], run.tags["f"])
        cells.setdefault(key, []).append(attack_succeeded(run.tags["track"], s.max_abs_dev_m, s.consequence))
        state = s.attack_state or {}
        if state.get("switch_time") is not None:
            giveway.setdefault(key, []).append(state["switch_time"] - run.tags["start"])
    lines = []
    for track in FR_TRACKS:
        lines += [f"**{track}** (goal {ATTACK_GOAL_M[track]} m): success rate, time from attack start to MSF give-way",
                  "", "| d \\ f | " + " | ".join(f"{f:g}" for f in GRID_F) + " |",
                  "|---|" + "---|" * len(GRID_F)]
        for d in GRID_D:
            row = []
            for f in GRID_F:
                res = cells.get((track, d, f), [])
                gw = giveway.get((track, d, f), [])
                spread = f"; give-way {np.min(gw):.1f}–{np.max(gw):.1f} s" if gw else ""
                row.append(f"{100 * np.mean(res):.0f}% ({len(res)}){spread}" if res else "–")
            lines.append(f"| {d:g} | " + " | ".join(row) + " |")
        lines.append("")
    _save_grid_heatmap(out / "fusionripper_grid.png", cells)
    lines.append("![success rate per d × f cell](fusionripper_grid.png)")
    return "\n".join(lines)


CAMPAIGNS: Registry[CampaignSpec] = Registry("campaign", CampaignSpec, "ld3.campaigns")
for _spec in (
    CampaignSpec("lane-keeping", "benign lane keeping with the true pose, and a 4 m/s² stop from 27 m/s",
                 lane_keeping_runs, lane_keeping_table),
    CampaignSpec("lane-keeping-msf", "benign lane keeping steered on the MSF (GNSS + LiDAR locator + IMU), "
                 "5 seeds per track", lane_keeping_msf_runs, lane_keeping_msf_table),
    CampaignSpec("table4", "urban-straight 12 m/s, default trace injection, 5 start times × none/naive/LD3",
                 table4_runs, defense_table),
    CampaignSpec("fusionripper-ld3", "FusionRipper (d=1.0, f=1.5) through the MSF on local and highway, LD3: "
                 "3 held-out track seeds × 3 noise seeds × 5 start times per track",
                 fusionripper_ld3_runs, defense_table),
    CampaignSpec("fusionripper-two-way", "FusionRipper (d=1.0, f=1.5) steering the car over the centre line of a "
                 "two-way road into oncoming traffic (8 cars): 3 held-out layouts × 2 noise seeds × 3 start times, "
                 "no defense and LD3", fusionripper_two_way_runs, defense_table),
    CampaignSpec("benign", "benign LD3 runs on every preset, 5 seeds each: false alarms", benign_runs, benign_table),
    CampaignSpec("benign-traffic", "benign LD3 runs in traffic (6 cars at the ego's speed, a lead car close ahead "
                 "in the ego lane, oncoming cars on the two-way road) on every preset × camera condition, 3 seeds, "
                 "15 s, the neural detector: false alarms and the tracked D_LD error",
                 benign_traffic_runs, benign_traffic_table),
    CampaignSpec("fusionripper-grid", "FusionRipper d×f grid without defense, 20 drives per cell (start time, "
                 "noise seed and road layout vary; paper Table 2)" + LATER_NOTE, fr_grid_runs, fr_grid_table,
                 figures_later=True),
    CampaignSpec("ablation", "LD3 response variants (paper mode first) × FusionRipper, trace, drp-trace, "
                 "drp-bend, stealthy × held-out local, highway, urban-straight; oracle detector" + LATER_NOTE,
                 ablation_runs, ablation_table, figures_later=True),
    CampaignSpec("roc", "LD3 vs SAVIOR detection ROC over (b, τ): benign and FusionRipper drives on local and "
                 "highway, residuals recorded once, swept offline", roc_runs, roc_table, record_detection_run),
    CampaignSpec("cusum-fit", "LD3's CUSUM (b, τ) refit for the lane detector: benign drives of every preset × "
                 "condition (held-out layouts, 3 seeds) and the Table 4 trace injection, recorded once, swept "
                 "offline", cusum_fit_runs, cusum_fit_table, record_detection_run),
    CampaignSpec("cusum-check", "the cusum-fit drives on layouts and noise seeds it never drove (a second held-out "
                 "layout per preset × condition, seeds 3–5; the trace injection with seeds 1–2): whether a (b, τ) "
                 "chosen there holds", cusum_check_runs, cusum_fit_table, record_detection_run),
    CampaignSpec("sim-table", "paper simulator table: default trace injection × LD3 / NaiveAR / none, 10 start "
                 "times, and benign LD3, 10 seeds, on slr (10 and 20 m/s), urban-straight and urban-curvy",
                 sim_table_runs, sim_table),
    CampaignSpec("stealthy", "stealthy attacker against LD3's CUSUM with each lane detector (oracle, classical, "
                 "neural), margins 0, 1 and 3 σ of that detector's LD noise, on local and highway",
                 stealthy_runs, stealthy_table),
    CampaignSpec("drp-ar", "DRP during the attack response, LD3: the DRP deviation trace on local, highway, "
                 "urban-straight and a painted road patch on urban-straight", drp_runs, drp_table),
    CampaignSpec("adaptive", "security margins: a worst-case attack search per road (local, highway, urban-curvy) "
                 "× defense (none, NaiveAR, SAVIOR, LD3 paper mode, LD3 default) × threat model (gnss, msf-output, "
                 "ld-output, both)", adaptive_runs, adaptive_table, searches=run_cells),
    CampaignSpec("maps", "OpenDRIVE maps (--maps: folders or files): each file's default route at 15 m/s with LD3, "
                 "benign (oracle and the lane detector) and under the default trace injection", lambda detector: [],
                 map_table, on_maps=map_runs),
):
    CAMPAIGNS.add(_spec)


def selected_runs(name: str, detector: str = "neural", select: str | None = None,
                  settings: Sequence[str] = (), attacks: Sequence[str] = (),
                  budget: int | None = None, maps: Sequence[str] = ()) -> list[CampaignRun]:
    """The runs of campaign `name` whose id matches one of the comma-separated globs `select` (all when None),
    with the `--attack` specs `attacks` composed after each run's own attacks and the `--set KEY=VALUE`
    `settings` applied to every run's scenario; `budget` is the trials of each search of a search campaign,
    `maps` the OpenDRIVE files or folders of a campaign over maps."""
    spec = CAMPAIGNS.get(name)
    if spec.on_maps is None and maps:
        raise UserError(f"--maps names the OpenDRIVE files of a campaign over maps; {name!r} is not one: drop it")
    if spec.on_maps is not None and not maps:
        raise UserError(f"campaign {name!r} drives OpenDRIVE files: add --maps DIR|FILE ...")
    runs = spec.on_maps(detector, maps) if spec.on_maps is not None else spec.build(detector)
    if budget is not None:
        if spec.searches is None:
            raise UserError(f"--budget sets the trials of a search campaign; {name!r} runs fixed scenarios: drop it")
        runs = with_budget(runs, budget)
    if select is not None:
        globs = [g.strip() for g in select.split(",") if g.strip()]
        runs = [r for r in runs if any(fnmatch.fnmatchcase(r.run_id, g) for g in globs)]
        if not runs:
            raise UserError(f"--runs {select!r} matches no run of campaign {name!r}")
    if attacks:
        runs = [dataclasses.replace(r, scenario=add_attacks(r.scenario, list(attacks))) for r in runs]
    if settings:
        runs = [dataclasses.replace(r, scenario=apply_settings(r.scenario, list(settings))) for r in runs]
    return runs


def _where(spec: CampaignSpec, out: Path, figures: bool) -> str:
    if spec.searches is not None:
        return "Each cell's search (trials.csv, report.md, best.toml) in its sub-folder."
    where = "Per-run outputs in the sub-folders; all summaries in runs.csv."
    if not figures:
        where += (f" The runs left their figures (birdseye.png, ar_fusion.png) for later: `ld3 figures {out}` draws "
                  f"them from believed.csv and the other outputs.")
    return where


def figures_choice(spec: CampaignSpec, figures: bool | None) -> bool:
    """Whether the runs of `spec` draw their figures at their end: `figures` when given (`--figures-now`,
    `--figures-later`, refused in one line for runs that do not write the standard outputs), else the
    campaign's own choice (`CampaignSpec.figures_later`)."""
    if figures is None:
        return not spec.figures_later
    if spec.execute is not run_and_write or spec.searches is not None:
        flag = "--figures-now" if figures else "--figures-later"
        raise UserError(f"{flag}: campaign {spec.name}'s runs do not write the standard run outputs (a search's "
                        f"trials leave their figures for later anyway); drop it")
    return figures


def run_named(name: str, out: Path, *, detector: str = "neural", workers: int | None = None, progress: bool = True,
              select: str | None = None, settings: Sequence[str] = (), timeout: float | None = None,
              backend: str = "local", address: str | None = None, attacks: Sequence[str] = (),
              budget: int | None = None, maps: Sequence[str] = (), figures: bool | None = None) -> Path:
    """Run campaign `name` into `out` and write its report; `select` is a comma-separated list of globs over
    run ids (all when None), `settings` are `--set KEY=VALUE` overrides applied to every run's scenario,
    `timeout` the time limit of each run in seconds (default `run_timeout`); `workers`, `backend` and
    `address` as `run_campaign`'s. `figures` chooses whether the runs draw their figures at their end or leave
    them to `ld3 figures` (`run_and_write_data`); None: the campaign's choice (`figures_choice`)."""
    spec = CAMPAIGNS.get(name)
    figures = figures_choice(spec, figures)
    execute = spec.execute if figures else run_and_write_data
    # the workers start (and load the simulation) while this process builds the runs (`run_campaign` checks the
    # backend and the address)
    with CAMPAIGN_BACKENDS.get(backend).kept_warm(workers, start=True):
        runs = selected_runs(name, detector, select, settings, attacks, budget, maps)
        if spec.searches is not None:
            done = spec.searches(runs, out, workers=workers, backend=backend, address=address, timeout=timeout,
                                 progress=progress)
        else:
            done = run_campaign(runs, out, workers=workers, progress=progress, execute=execute, timeout=timeout,
                                backend=backend, address=address)
    used = ", ".join(f"`{d}`" for d in sorted({run.scenario.detector for run in runs}))
    report = out / "report.md"
    overrides = "".join(f" Every run with {flag} `{' '.join(values)}`." for flag, values
                        in (("--attack", attacks), ("--set", settings)) if values)
    report.write_text(f"# Campaign {name}\n\n{spec.help}; lane detector {used}.{overrides}\n\n"
                      f"{spec.table(done, out)}\n\n{_where(spec, out, figures)}\n")
    return report
