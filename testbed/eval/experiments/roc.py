"""The detection ROC campaign (`ld3 campaign roc`): LD3 against SAVIOR, like the paper's ROC figure.

Runs, on `local` and `highway` with the MSF and no response (a `DetectionRecorder` rides along):
benign drives (10 seeds), FusionRipper drives (two (d, f) settings × 5 start times), and two extra benign
drives per track (seeds 100, 101) that only serve to fit SAVIOR's bicycle coefficients. Each run writes
the standard outputs plus `detection_log.npz`. The table then, without simulating again: fits the bicycle
model on the fit drives' true trajectories and commands, replays SAVIOR's EKF on every logged run,
sweeps (b, τ) for both detectors (testbed.defense.roc) and draws `roc.png`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.defense.bicycle import LOG_COLUMNS, BicycleCoefficients, fit_bicycle_coefficients
from testbed.defense.config import DefenseConfig
from testbed.defense.recorder import DetectionRecorder, load_detection_log
from testbed.defense.roc import ResidualSeries, RocPoint, ld3_series, replay_savior, roc_auc, roc_frontier, roc_sweep
from testbed.defense.savior import SaviorConfig
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.run.consequence import attack_succeeded
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.scenario import load_scenario
from testbed.eval.run.summary import RunSummary

ROC_TRACKS = {"local": 12.0, "highway": 27.0}
ROC_ATTACKS = ({"d": 1.0, "f": 1.5}, {"d": 0.5, "f": 1.2})
ROC_STARTS = (8.0, 13.0, 18.0, 23.0, 28.0)
BENIGN_SEEDS = tuple(range(10))
FIT_SEEDS = (100, 101)
LOG_NAME = "detection_log.npz"

_DEFAULTS = DefenseConfig()
_SAVIOR_DEFAULTS = SaviorConfig()
LD3_BS = np.round(np.arange(0.0, 1.51, 0.05), 3)
LD3_TAUS = np.union1d(np.concatenate([[0.0], np.geomspace(0.01, 50.0, 60)]), [_DEFAULTS.tau])
SAVIOR_BS = np.round(np.arange(0.0, 6.01, 0.25), 3)
SAVIOR_TAUS = np.union1d(np.concatenate([[0.0], np.geomspace(0.05, 500.0, 60)]), [_SAVIOR_DEFAULTS.savior_tau])


def roc_runs(detector: str) -> list[CampaignRun]:
    """Benign, fit and FusionRipper drives on each ROC track (module docstring), all without response."""
    runs = []
    for track, speed in ROC_TRACKS.items():
        base = load_scenario(track).with_overrides(speed=speed, duration=60.0, detector=detector,
                                                   localization="msf", defense="none")
        for seed in (*BENIGN_SEEDS, *FIT_SEEDS):
            role = "fit" if seed in FIT_SEEDS else "benign"
            runs.append(CampaignRun(f"{track}-{role}-seed{seed}", base.with_overrides(seed=seed, name=f"roc-{track}"),
                                    {"track": track, "role": role, "seed": seed}))
        for attack in ROC_ATTACKS:
            for start in ROC_STARTS:
                spec = {"kind": "fusionripper", **attack, "start": start}
                runs.append(CampaignRun(
                    f"{track}-fr-d{attack['d']:g}-f{attack['f']:g}-start{start:g}",
                    base.with_overrides(duration=50.0, attack=spec, name=f"roc-{track}"),
                    {"track": track, "role": "attacked", "start": start, **attack}))
    return runs


def record_detection_run(run: CampaignRun, run_dir: Path) -> RunSummary:
    """Executor: the run with a `DetectionRecorder` as its defense; its outputs plus detection_log.npz."""
    from testbed.eval.run.runner import SimRun, prepare_out_dir

    prepare_out_dir(run_dir)
    config = DefenseConfig.from_dict(run.scenario.defense_params)
    recorder = DetectionRecorder(config.existence_threshold, config.ld_lines)
    sim = SimRun(run.scenario, defense=recorder)
    try:
        result = sim.run()
        recorder.log.save(run_dir / LOG_NAME)
        sim.write_outputs(run_dir, result, title_suffix=" · detection recorder")
        return result.record
    finally:
        sim.close()


def _trajectory_log(run_dir: Path) -> np.ndarray:
    """A fit log (columns `LOG_COLUMNS`) from trajectory.csv: true pose, speed and the commands sent."""
    cols = read_trajectory(run_dir, LOG_COLUMNS)
    return np.column_stack([cols[c] for c in LOG_COLUMNS])


def fit_savior(out: Path, runs: list[CampaignRun], wheelbase: float) -> BicycleCoefficients:
    """SAVIOR's bicycle coefficients fitted (scipy least squares) on the finished drives `runs` in `out`."""
    logs = [_trajectory_log(out / r.run_id) for r in runs]
    return fit_bicycle_coefficients(logs, wheelbase)


def _series(out: Path, done: list[tuple[CampaignRun, RunSummary]], coefficients: BicycleCoefficients,
            ) -> dict[str, dict[str, list[ResidualSeries]]]:
    """{track: {"ld3": [...], "savior": [...]}} over the benign runs and the attacked runs whose attack
    succeeded (paper Table 2's rule): a failed attack leaves nothing to detect (like the paper's traces,
    all of which the attack succeeds on)."""
    result: dict[str, dict[str, list[ResidualSeries]]] = {}
    for run, summary in done:
        if run.tags["role"] == "fit":
            continue
        if run.tags["role"] == "attacked" and not attack_succeeded(
                run.tags["track"], summary.max_abs_dev_m, summary.consequence):
            continue
        log = load_detection_log(out / run.run_id / LOG_NAME)
        start = run.tags.get("start")
        per = result.setdefault(run.tags["track"], {"ld3": [], "savior": []})
        per["ld3"].append(ld3_series(log["ld3"], start))
        per["savior"].append(replay_savior(log, coefficients, start))
    return result


def _point_at(points: list[RocPoint], b: float, tau: float) -> RocPoint:
    return min(points, key=lambda p: (abs(p.b - b), abs(p.tau - tau)))


def _best(points: list[RocPoint], b0: float, tau0: float) -> RocPoint:
    """The (b, τ) with the largest TPR − FPR (Youden's J); on ties the one nearest the default (b0, τ0)."""
    def distance(p: RocPoint) -> float:
        return abs(p.b - b0) / max(b0, 1e-9) + abs(p.tau - tau0) / max(tau0, 1e-9)

    return max(points, key=lambda p: (p.tpr - p.fpr, -distance(p)))


def roc_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    from testbed.presets import vehicle

    fit_runs = [r for r, _ in done if r.tags["role"] == "fit"]
    if not fit_runs:
        return "No fit drive finished; SAVIOR cannot be fitted yet."
    wheelbase = vehicle(fit_runs[0].scenario.vehicle).wheelbase
    coefficients = fit_savior(out, fit_runs, wheelbase)
    series = _series(out, done, coefficients)
    if not series:
        return (f"SAVIOR bicycle model fitted on {len(fit_runs)} benign drives: {coefficients}. No benign or "
                "attacked drive finished, so there is no ROC to sweep yet.")
    grids = {"ld3": (LD3_BS, LD3_TAUS, _DEFAULTS.b, _DEFAULTS.tau),
             "savior": (SAVIOR_BS, SAVIOR_TAUS, _SAVIOR_DEFAULTS.savior_b, _SAVIOR_DEFAULTS.savior_tau)}
    failed = sum(r.tags["role"] == "attacked" and not attack_succeeded(r.tags["track"], s.max_abs_dev_m,
                                                                       s.consequence) for r, s in done)
    lines = [f"SAVIOR bicycle model fitted on {len(fit_runs)} benign drives: {coefficients}.",
             f"Attacked runs whose attack failed (left out of the TPR): {failed}.", "",
             "| track | detector | benign runs | attacked runs | AUC | best (b, τ): FPR, TPR "
             "| default (b, τ): FPR, TPR |", "|---|---|---|---|---|---|---|"]
    fig = Figure(figsize=(5.0 * len(series), 4.8))
    axes = fig.subplots(1, len(series), squeeze=False)
    for ax, (track, per) in zip(axes[0], sorted(series.items()), strict=True):
        ax.plot([0, 1], [0, 1], color="0.6", ls=":", lw=1, label="random guess")
        for name, ser in per.items():
            bs, taus, b0, tau0 = grids[name]
            try:
                points = roc_sweep(ser, bs, taus)
            except ValueError as exc:
                lines.append(f"| {track} | {name} | – | – | {exc} | | |")
                continue
            curve = roc_frontier(points)
            auc = roc_auc(curve)
            best, default = _best(points, b0, tau0), _point_at(points, b0, tau0)
            n_benign = sum(s.attack_start is None for s in ser)
            lines.append(f"| {track} | {name} | {n_benign} | {len(ser) - n_benign} | {auc:.2f} "
                         f"| ({best.b:g}, {best.tau:.3g}): {best.fpr:.2f}, {best.tpr:.2f} "
                         f"| ({default.b:g}, {default.tau:.3g}): {default.fpr:.2f}, {default.tpr:.2f} |")
            fx, fy = zip(*curve, strict=True)
            (line,) = ax.step(fx, fy, where="post", lw=2, label=f"{name.upper()} (AUC {auc:.2f})")
            ax.scatter([p.fpr for p in points], [p.tpr for p in points], s=6, alpha=0.15, color=line.get_color())
            ax.scatter([default.fpr], [default.tpr], marker="*", s=120, color=line.get_color(), edgecolor="k",
                       zorder=5, label=f"{name.upper()} default b={b0:g}, τ={tau0:g}")
        ax.set_xlim(-0.02, 1.02)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("false positive rate")
        ax.set_ylabel("true positive rate")
        ax.set_title(f"{track}: FusionRipper detection ROC")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "roc.png", dpi=110)
    lines += ["", "Each faint dot is one swept (b, τ); the step line is the best TPR reached at each FPR.",
              "", "![ROC](roc.png)"]
    return "\n".join(lines)
