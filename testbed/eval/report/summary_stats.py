"""Statistics over finished runs' summaries for report tables: mean and spread of a summary field,
consequence counts, and the deviation a run reached before any alarm."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence

import numpy as np

from testbed.eval.run.summary import RunSummary


def finite(values: Iterable[float | None]) -> np.ndarray:
    """The values that are numbers (None and NaN dropped)."""
    arr = np.array([v for v in values if v is not None], dtype=float)
    return arr[np.isfinite(arr)]


def mean_sd(values: Iterable[float | None]) -> tuple[float, float] | None:
    """(mean, population std) of the values that are numbers, or None when there are none."""
    arr = finite(values)
    return (float(arr.mean()), float(arr.std())) if arr.size else None


def fmt_mean_sd(values: Iterable[float | None], digits: int = 2) -> str:
    """'mean, std' as the paper's tables write it, or '–'."""
    stats = mean_sd(values)
    return "–" if stats is None else f"{stats[0]:.{digits}f}, {stats[1]:.{digits}f}"


def consequences(summaries: Sequence[RunSummary]) -> str:
    """'stop_in_lane ×3, hit_curb ×1', most frequent first (ties by name)."""
    counts = Counter(s.consequence for s in summaries)
    return ", ".join(f"{k} ×{v}" for k, v in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def undetected_dev(summary: RunSummary) -> float | None:
    """Largest |physical D| the attack reached without an alarm: before detection, or over the run if none."""
    return summary.detection_dev_m if summary.detected else summary.max_abs_dev_m


def abs_or_none(value: float | None) -> float | None:
    return None if value is None else abs(value)


def response_max_dev(summary: RunSummary) -> float | None:
    """Max |physical D| during the attack response where one ran, else over the whole run."""
    return summary.ar_max_dev_m if summary.ar_max_dev_m is not None else summary.max_abs_dev_m


def stop_dev(summary: RunSummary) -> float | None:
    """|D| where the response stopped the car, else at the end of the run."""
    return abs_or_none(summary.ar_stop_dev_m if summary.ar_stop_dev_m is not None else summary.final_dev_m)
