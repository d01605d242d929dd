"""Offline CUSUM (b, τ) sweeps over recorded residual series: ROC curves of LD3 and SAVIOR (paper §5.2).

A series is the residuals one detector fed its CUSUM in a run, in order, with their times and segment
numbers: S restarts at 0 where the segment changes (LD3 after an intersection). For a fixed b the path
S_i = max(0, S_{i-1} + |r_i| − b) does not depend on τ up to the alarm, so the first alarm under τ is the
first i whose running maximum M_i = max_{j≤i} S_j exceeds τ: one pass per (series, b) answers every τ.

Rates: a benign run with any alarm is a false positive. An attacked run is a true positive when its first
alarm comes at or after the attack start; an alarm before the start is a false alarm in that run, not a
detection. FPR = false positives / benign runs, TPR = true positives / attacked runs.

SAVIOR's residuals are not logged in the closed loop but recomputed (`replay_savior`) from the inputs a
`DetectionRecorder` logged, so the bicycle coefficients can be fitted after the runs.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from testbed.defense.attack_detection import Cusum
from testbed.defense.bicycle import BicycleCoefficients
from testbed.defense.savior import SaviorConfig, SaviorDefense
from testbed.localization.estimate import LocalizationEstimate
from tracks.pose import Pose


@dataclass(frozen=True)
class ResidualSeries:
    """Residuals r (m) at times t (s) with segment numbers; `attack_start` is None for a benign run."""

    t: np.ndarray
    r: np.ndarray
    segment: np.ndarray
    attack_start: float | None = None


@dataclass(frozen=True)
class RocPoint:
    b: float
    tau: float
    fpr: float
    tpr: float


def cusum_running_max(r: np.ndarray, segment: np.ndarray, b: float) -> np.ndarray:
    """M_i = max_{j≤i} S_j of the unlatched CUSUM over |r| with weight b, S reset at segment changes."""
    out = np.empty(len(r))
    s, m = 0.0, 0.0
    prev = None
    for i, (ri, seg) in enumerate(zip(np.abs(r).tolist(), segment.tolist(), strict=True)):
        if seg != prev:
            s, prev = 0.0, seg
        s = max(0.0, s + ri - b)
        m = max(m, s)
        out[i] = m
    return out


def first_alarm_times(series: ResidualSeries, b: float, taus: np.ndarray) -> np.ndarray:
    """Time of the first alarm of CUSUM(b, τ) for each τ in `taus`; NaN where it never alarms."""
    taus = np.asarray(taus, dtype=float)
    if len(series.r) == 0:
        return np.full(taus.shape, np.nan)
    m = cusum_running_max(series.r, series.segment, b)
    idx = np.searchsorted(m, taus, side="right")  # first i with M_i > τ
    out = np.full(taus.shape, np.nan)
    hit = idx < len(m)
    out[hit] = series.t[idx[hit]]
    return out


def roc_sweep(series: Sequence[ResidualSeries], bs: Sequence[float], taus: Sequence[float]) -> list[RocPoint]:
    """(FPR, TPR) for every (b, τ) over the benign and attacked runs in `series` (module docstring)."""
    benign = [s for s in series if s.attack_start is None]
    attacked = [s for s in series if s.attack_start is not None]
    if not benign or not attacked:
        raise ValueError(f"a ROC needs benign and attacked runs; got {len(benign)} benign, {len(attacked)} attacked")
    tau_arr = np.asarray(taus, dtype=float)
    points = []
    for b in bs:
        fp = np.zeros(len(tau_arr))
        tp = np.zeros(len(tau_arr))
        for s in benign:
            fp += np.isfinite(first_alarm_times(s, b, tau_arr))
        for s in attacked:
            alarm = first_alarm_times(s, b, tau_arr)
            tp += np.isfinite(alarm) & (alarm >= s.attack_start)
        points += [RocPoint(float(b), float(tau), float(f / len(benign)), float(p / len(attacked)))
                   for tau, f, p in zip(tau_arr, fp, tp, strict=True)]
    return points


def roc_frontier(points: Sequence[RocPoint]) -> list[tuple[float, float]]:
    """The ROC curve of the best (b, τ) at each FPR: a staircase from (0, 0) through the best TPR reached
    at or below each swept FPR, held out to FPR = 1. It is not closed at (1, 1): an always-alarming
    detector alarms before the attack starts, which is no detection."""
    best: dict[float, float] = {}
    for p in points:
        best[p.fpr] = max(best.get(p.fpr, 0.0), p.tpr)
    curve = [(0.0, 0.0)]
    for fpr in sorted(best):
        curve.append((fpr, max(best[fpr], curve[-1][1])))
    if curve[-1][0] < 1.0:
        curve.append((1.0, curve[-1][1]))
    return curve


def roc_auc(curve: Sequence[tuple[float, float]]) -> float:
    """Area under a staircase ROC curve (TPR held until the next FPR reached)."""
    return float(sum((f1 - f0) * t0 for (f0, t0), (f1, _) in itertools.pairwise(curve)))


def ld3_series(ld3_rows: np.ndarray, attack_start: float | None) -> ResidualSeries:
    """LD3's residual series r = D_MSF − D_LD from a DetectionLog's ld3 rows (t, D_MSF, D_LD, segment)."""
    rows = np.asarray(ld3_rows, dtype=float).reshape(-1, 4)
    return ResidualSeries(rows[:, 0], rows[:, 1] - rows[:, 2], rows[:, 3].astype(int), attack_start)


class _LoggingCusum(Cusum):
    """A CUSUM that never alarms and keeps every residual it is fed."""

    def __init__(self) -> None:
        super().__init__(b=0.0, tau=math.inf)
        self.residuals: list[float] = []

    def update(self, residual: float) -> bool:
        self.residuals.append(residual)
        return super().update(residual)


def replay_savior(
    log: dict[str, np.ndarray],
    coefficients: BicycleCoefficients,
    attack_start: float | None,
    config: SaviorConfig | None = None,
) -> ResidualSeries:
    """SAVIOR's GNSS residual series, re-running its EKF on a DetectionLog's inputs in the loop's order
    within a tick (GNSS fix, then the lane detection that may start the EKF, then the command)."""
    defense = SaviorDefense(config or SaviorConfig(), coefficients)
    cusum = _LoggingCusum()
    defense.cusum = cusum
    times: list[float] = []
    events: list[tuple[float, int, int]] = []
    for rank, key in enumerate(("gnss", "init", "commands")):
        events += [(float(row[0]), rank, i) for i, row in enumerate(log[key])]
    for t, rank, i in sorted(events):
        if rank == 0:
            _, x, y, cxx, cxy, cyy = log["gnss"][i]
            before = len(cusum.residuals)
            defense.on_gnss(t, np.array([x, y]), np.array([[cxx, cxy], [cxy, cyy]]))
            if len(cusum.residuals) > before:
                times.append(t)
        elif rank == 1:
            _, x, y, yaw, vx, vy, vyaw = log["init"][i]
            defense.start_from(LocalizationEstimate(t, Pose(x, y, yaw), np.diag([vx, vy, vyaw])))
        else:
            _, steer, accel, speed = log["commands"][i]
            defense.on_command(t, steer, accel, speed)
    r = np.array(cusum.residuals)
    return ResidualSeries(np.array(times), r, np.zeros(len(r), dtype=int), attack_start)

