"""The CUSUM refit campaign (`ld3 campaign cusum-fit`): how small LD3's b can be with the lane detector in use.

Runs, with the MSF and no response (a `DetectionRecorder` rides along, as in the ROC campaign): benign
drives of every benign preset under every camera condition, on held-out track seeds (one layout per
preset and condition, as `ld3 ld closed-loop` drives), 3 noise seeds each; and the Table 4 attack (default
trace injection on urban-straight at 12 m/s, 5 start times). The table then replays LD3's CUSUM offline
for every b of the grid: the largest benign CUSUM (any τ at or above it has no false alarm), the false
alarms at the shipped τ, and on the attacked drives the detections and the detection deviation (the
largest true |lateral deviation| up to the first alarm; a recorder drive is the LD3 drive up to there), at
the shipped τ and at that smallest clean τ, whose best b is the earliest clean (b, τ) pair.
`ld3 campaign cusum-check` drives the same on layouts and noise seeds the fit never saw, with the same table.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.conditions import CONDITIONS
from testbed.defense.config import DefenseConfig
from testbed.defense.recorder import load_detection_log
from testbed.defense.roc import ResidualSeries, cusum_running_max, first_alarm_times, ld3_series
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.experiments.roc import LD3_BS, LOG_NAME
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary
from testbed.perception.training.seeds import Cell, cells, check_cells

FIT_PRESETS = ("slr", "urban-straight", "urban-curvy", "highway", "local", "parking-lot")
FIT_SEEDS = (0, 1, 2)
CHECK_SEEDS = (3, 4, 5)
CHECK_ATTACK_SEEDS = (1, 2)
BENIGN_DURATION_S = 60.0
ATTACK_STARTS = (6.0, 8.0, 10.0, 12.0, 14.0)
TABLE_MAX_B = 1.0  # b shown in report.md (every b of the grid is in cusum_fit.csv)

_SHIPPED = DefenseConfig()


def _runs(detector: str, layouts: list[Cell], seeds: tuple[int, ...], attack_seeds: tuple[int, ...],
          name: str) -> list[CampaignRun]:
    runs = []
    for cell in layouts:
        base = load_scenario(cell.preset)
        sc = base.with_overrides(track=f"{cell.preset}@{cell.track_seed}", condition=cell.condition,
                                 duration=min(BENIGN_DURATION_S, base.duration), detector=detector,
                                 localization="msf", defense="none", name=f"{name}-{cell.preset}")
        for seed in seeds:
            runs.append(CampaignRun(f"benign/{cell.preset}-{cell.condition}-seed{seed}", sc.with_overrides(seed=seed),
                                    {"role": "benign", "preset": cell.preset, "condition": cell.condition,
                                     "seed": seed}))
    attacked = load_scenario("urban-straight").with_overrides(speed=12.0, duration=40.0, detector=detector,
                                                              localization="msf", defense="none")
    for seed in attack_seeds:
        for start in ATTACK_STARTS:
            runs.append(CampaignRun(f"trace/start{start:g}" + (f"-seed{seed}" if seed else ""), attacked.with_overrides(
                attack={"kind": "trace", "trace": "default", "start": start}, name=f"{name}-trace", seed=seed),
                {"role": "attacked", "start": start, "seed": seed}))
    return runs


def cusum_fit_runs(detector: str) -> list[CampaignRun]:
    """Benign drives (preset × condition × seed, held-out layouts) and the Table 4 trace injection, recorded."""
    return _runs(detector, cells(list(FIT_PRESETS), list(CONDITIONS)), FIT_SEEDS, (0,), "cusum-fit")


def cusum_check_runs(detector: str) -> list[CampaignRun]:
    """The same drives on layouts and seeds the refit never drove (`check_cells`, noise seeds 3–5; the trace
    injection with noise seeds 1 and 2): whether a (b, τ) chosen on `cusum_fit_runs` holds beyond them."""
    return _runs(detector, check_cells(list(FIT_PRESETS), list(CONDITIONS)), CHECK_SEEDS, CHECK_ATTACK_SEEDS,
                 "cusum-check")


def detection_dev(series: ResidualSeries, t: np.ndarray, phys_dev: np.ndarray, b: float, tau: float) -> float:
    """The largest true |lateral deviation| up to the first alarm of CUSUM(b, τ) at or after the attack start;
    NaN where it does not alarm there (no detection)."""
    (alarm,) = first_alarm_times(series, b, np.array([tau]))
    if not np.isfinite(alarm) or alarm < series.attack_start:
        return float("nan")
    return float(np.nanmax(np.abs(phys_dev[t <= alarm + 1e-9])))


def benign_peaks(series: list[ResidualSeries], b: float) -> np.ndarray:
    """The largest CUSUM statistic each series reaches with weight b: it alarms under τ iff its peak is over τ."""
    return np.array([float(cusum_running_max(s.r, s.segment, b)[-1]) if len(s.r) else 0.0 for s in series])


def largest_benign_cusum(series: list[ResidualSeries], b: float) -> float:
    """The largest CUSUM statistic any benign series reaches with weight b: every τ at or above it is free of
    false alarms on them."""
    return float(benign_peaks(series, b).max())


def _detections(attacked: list[tuple[ResidualSeries, np.ndarray, np.ndarray]], b: float, tau: float
                ) -> tuple[int, float, float]:
    """Detections of CUSUM(b, τ) among the attacked drives, and their detection deviations' mean and max (m)."""
    devs = np.array([detection_dev(s, t, d, b, tau) for s, t, d in attacked])
    hit = devs[np.isfinite(devs)]
    return len(hit), float(hit.mean()) if len(hit) else float("nan"), float(hit.max()) if len(hit) else float("nan")


def sweep(benign: list[ResidualSeries], attacked: list[tuple[ResidualSeries, np.ndarray, np.ndarray]],
          bs: np.ndarray, tau: float) -> list[dict[str, float]]:
    """Per b: the largest benign CUSUM, false alarms at τ, detections at τ and their deviations (m); and at the
    smallest τ free of benign alarms (`clean_tau`, the largest benign CUSUM) the same detections."""
    rows = []
    for b in bs:
        peaks = benign_peaks(benign, float(b))
        detected, mean, worst = _detections(attacked, float(b), tau)
        clean_tau = float(peaks.max())
        clean_detected, clean_mean, clean_worst = _detections(attacked, float(b), clean_tau)
        rows.append({"b": float(b), "largest_benign_cusum": clean_tau,
                     "false_alarms": int((peaks > tau).sum()), "detected": detected, "attacked": len(attacked),
                     "detection_dev_mean": mean, "detection_dev_max": worst,
                     "clean_tau_detected": clean_detected, "clean_tau_detection_dev_mean": clean_mean,
                     "clean_tau_detection_dev_max": clean_worst})
    return rows


def earliest_clean_pair(rows: list[dict[str, float]]) -> dict[str, float] | None:
    """The row whose b, with τ at its smallest clean value, detects every attacked drive with the smallest
    largest detection deviation: the (b, τ) pair that alarms earliest with no benign alarm; None if none."""
    ok = [r for r in rows if r["clean_tau_detected"] == r["attacked"]]
    return min(ok, key=lambda r: (r["clean_tau_detection_dev_max"], r["b"])) if ok else None


def smallest_clean_b(rows: list[dict[str, float]], tau: float, headroom: float = 1.0) -> dict[str, float] | None:
    """The row of the smallest b whose largest benign CUSUM stays at or below τ / headroom and that detects
    every attacked drive; None if no b does."""
    ok = [r for r in rows if r["largest_benign_cusum"] * headroom <= tau and r["detected"] == r["attacked"]]
    return min(ok, key=lambda r: r["b"]) if ok else None


def _series(out: Path, done: list[tuple[CampaignRun, RunSummary]]):
    benign: list[tuple[CampaignRun, ResidualSeries]] = []
    attacked: list[tuple[ResidualSeries, np.ndarray, np.ndarray]] = []
    for run, _ in done:
        log = load_detection_log(out / run.run_id / LOG_NAME)
        if run.tags["role"] == "benign":
            benign.append((run, ld3_series(log["ld3"], None)))
        else:
            cols = read_trajectory(out / run.run_id, ("t", "phys_dev"))
            attacked.append((ld3_series(log["ld3"], run.tags["start"]), cols["t"], cols["phys_dev"]))
    return benign, attacked


def _f(v: float) -> str:
    return "–" if not np.isfinite(v) else f"{v:.3f}"


def cusum_fit_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    benign, attacked = _series(out, done)
    if not benign or not attacked:
        return (f"{len(benign)} benign and {len(attacked)} attacked drives finished; the refit needs at least one "
                "of each.")
    b0, tau = _SHIPPED.b, _SHIPPED.tau
    rows = sweep([s for _, s in benign], attacked, LD3_BS, tau)
    keys = list(rows[0])
    (out / "cusum_fit.csv").write_text("\n".join([",".join(keys)] + [",".join(f"{r[k]:g}" for k in keys)
                                                                      for r in rows]) + "\n")
    lines = [f"{len(benign)} benign drives, {len(attacked)} attacked (Table 4 trace injection); shipped "
             f"b = {b0:g} m, τ = {tau:g} m.", ""]
    for headroom, what in ((1.0, "with no benign alarm"), (2.0, "with its largest benign CUSUM at most τ/2")):
        best = smallest_clean_b(rows, tau, headroom)
        lines.append(f"- Smallest b {what} at τ = {tau:g} that detects every attacked drive: " + (
            f"**b = {best['b']:g}**, detection deviation mean {_f(best['detection_dev_mean'])} m, max "
            f"{_f(best['detection_dev_max'])} m." if best else "none in the grid."))
    pair = earliest_clean_pair(rows)
    lines.append("- Earliest alarm over (b, τ) with no benign alarm (τ at the b's largest benign CUSUM): " + (
        f"**b = {pair['b']:g}, τ = {pair['largest_benign_cusum']:.3f}**, detection deviation mean "
        f"{_f(pair['clean_tau_detection_dev_mean'])} m, max {_f(pair['clean_tau_detection_dev_max'])} m."
        if pair else "none in the grid."))
    shipped = min(rows, key=lambda r: abs(r["b"] - b0))
    lines += [f"- Shipped b = {b0:g}: largest benign CUSUM {_f(shipped['largest_benign_cusum'])} m, "
              f"{shipped['false_alarms']} false alarms, detected {shipped['detected']}/{shipped['attacked']}, "
              f"detection deviation mean {_f(shipped['detection_dev_mean'])} m, max "
              f"{_f(shipped['detection_dev_max'])} m.", "",
              f"| b (m) | largest benign CUSUM (m) | false alarms at τ = {tau:g} | detected "
              "| detection dev mean (m) | detection dev max (m) | detected at τ = largest benign CUSUM "
              "| its detection dev mean / max (m) |", "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['b']:g} | {_f(r['largest_benign_cusum'])} | {r['false_alarms']}/{len(benign)} "
              f"| {r['detected']}/{r['attacked']} | {_f(r['detection_dev_mean'])} | {_f(r['detection_dev_max'])} "
              f"| {r['clean_tau_detected']}/{r['attacked']} | {_f(r['clean_tau_detection_dev_mean'])} / "
              f"{_f(r['clean_tau_detection_dev_max'])} |"
              for r in rows if r["b"] <= TABLE_MAX_B + 1e-9]
    lines += ["", f"Largest benign CUSUM (m) at the shipped b = {b0:g}, per preset and condition (τ = {tau:g}):",
              "", _condition_table(benign, b0), ""]
    clean = smallest_clean_b(rows, tau)
    below = [r["b"] for r in rows if clean is not None and r["b"] < clean["b"]]
    lines += [_alarm_table(benign, sorted({b0, *below[-1:]}), tau), "", "![refit](cusum_fit.png)"]
    _plot(rows, tau, out / "cusum_fit.png")
    return "\n".join(lines)


def benign_alarms(benign: list[tuple[CampaignRun, ResidualSeries]], b: float, tau: float
                  ) -> list[tuple[CampaignRun, float, float, float]]:
    """The benign drives CUSUM(b, τ) alarms on: (run, time of the first alarm, largest |residual| and its
    time)."""
    out = []
    for run, s in benign:
        (alarm,) = first_alarm_times(s, b, np.array([tau]))
        if np.isfinite(alarm):
            k = int(np.nanargmax(np.abs(s.r)))
            out.append((run, float(alarm), float(abs(s.r[k])), float(s.t[k])))
    return out


def _alarm_table(benign: list[tuple[CampaignRun, ResidualSeries]], bs: list[float], tau: float) -> str:
    """The benign drives that alarm at each b of `bs` (the report passes the shipped b and the grid b just under
    the smallest clean one: the drives that keep b from coming down)."""
    lines = [f"Benign drives that alarm (τ = {tau:g}):", "",
             "| b (m) | run | track | first alarm (s) | largest \\|residual\\| (m) | at (s) |",
             "|---|---|---|---|---|---|"]
    for b in bs:
        hits = benign_alarms(benign, b, tau)
        lines += [f"| {b:g} | {run.run_id} | {run.scenario.track} | {alarm:.2f} | {r:.3f} | {t:.2f} |"
                  for run, alarm, r, t in hits] or [f"| {b:g} | none | | | | |"]
    return "\n".join(lines)


def _condition_table(benign: list[tuple[CampaignRun, ResidualSeries]], b: float) -> str:
    conditions = [c for c in CONDITIONS if any(r.tags["condition"] == c for r, _ in benign)]
    presets = [p for p in FIT_PRESETS if any(r.tags["preset"] == p for r, _ in benign)]
    lines = ["| preset | " + " | ".join(conditions) + " |", "|---|" + "---|" * len(conditions)]
    for p in presets:
        cells_ = []
        for c in conditions:
            ser = [s for r, s in benign if r.tags["preset"] == p and r.tags["condition"] == c]
            cells_.append(_f(largest_benign_cusum(ser, b)) if ser else "–")
        lines.append(f"| {p} | " + " | ".join(cells_) + " |")
    return "\n".join(lines)


def _plot(rows: list[dict[str, float]], tau: float, path: Path) -> None:
    b = [r["b"] for r in rows]
    fig = Figure(figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    ax1.semilogy(b, [max(r["largest_benign_cusum"], 1e-4) for r in rows], marker=".")
    ax1.axhline(tau, color="r", ls="--", label=f"τ = {tau:g} m")
    ax1.axvline(_SHIPPED.b, color="0.5", ls=":", label=f"shipped b = {_SHIPPED.b:g} m")
    ax1.set_xlabel("b (m)")
    ax1.set_ylabel("largest benign CUSUM (m)")
    ax1.legend()
    ax1.grid(alpha=0.3)
    ax2.plot(b, [r["detection_dev_mean"] for r in rows], marker=".", label="mean")
    ax2.plot(b, [r["detection_dev_max"] for r in rows], marker=".", label="max")
    ax2.axvline(_SHIPPED.b, color="0.5", ls=":")
    ax2.set_xlabel("b (m)")
    ax2.set_ylabel(f"detection deviation at τ = {tau:g} m (m)")
    ax2.legend()
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
