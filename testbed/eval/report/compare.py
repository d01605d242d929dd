"""Reports of several runs side by side: a markdown table in the style of the paper's Table 4 and a plot
of the physical deviation of each run against time.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.errors import UserError
from testbed.eval.report.figures_later import draw_later
from testbed.eval.run.outputs import read_trajectory
from testbed.eval.run.summary import RunSummary, read_summary


@dataclass(frozen=True)
class ReportRow:
    """One run of the report: its label, its folder and its typed summary."""

    label: str
    run_dir: Path
    summary: RunSummary


def _fmt(v, digits: int = 2) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def _phys_dev(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    cols = read_trajectory(run_dir, ("t", "phys_dev"))
    known = np.isfinite(cols["phys_dev"])
    return cols["t"][known], cols["phys_dev"][known]


def plot_deviations(path: Path, rows: Sequence[ReportRow], title: str) -> None:
    fig = Figure(figsize=(9, 4.5))
    ax = fig.subplots()
    first = rows[0].summary
    half, straddle = first.lane_width_m / 2, first.lane_straddle_dev_m
    ax.axhspan(-straddle, straddle, color="0.92", label="no lane straddle")
    for edge in (-half, half):
        ax.axhline(edge, color="0.3", lw=1.2)
    for r in rows:
        t, d = _phys_dev(r.run_dir)
        (line,) = ax.plot(t, d, label=f"{r.label}: {r.summary.consequence}")
        det = r.summary.detection_time_s
        if det is not None:
            ax.axvline(det, color=line.get_color(), ls=":", lw=1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("physical lateral deviation D (m, + left)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def write_report(out_dir: Path, title: str, rows: Sequence[ReportRow], notes: str = "") -> Path:
    """report.md and deviations.png in `out_dir`; returns the report path."""
    plot_deviations(out_dir / "deviations.png", rows, title)
    lines = [f"# {title}", "", notes, "",
             "| run | defense | attack | consequence | detected | detection time (s) | detection dev (m) "
             "| AR max dev (m) | stop dev (m) | max abs dev (m) | lane straddle dev (m) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r.summary
        spec = s.attack
        attack = spec.get("kind", "?") if isinstance(spec, dict) else _fmt(spec)
        lines.append(
            f"| [{r.label}]({os.path.relpath(r.run_dir / 'birdseye.png', out_dir)}) | {s.defense} | {attack} "
            f"| {s.consequence} "
            f"| {_fmt(s.detected)} | {_fmt(s.detection_time_s)} | {_fmt(s.detection_dev_m)} "
            f"| {_fmt(s.ar_max_dev_m)} | {_fmt(s.ar_stop_dev_m)} | {_fmt(s.max_abs_dev_m)} "
            f"| {_fmt(s.lane_straddle_dev_m)} |")
    lines += ["", "![physical deviation of each run](deviations.png)", ""]
    path = out_dir / "report.md"
    path.write_text("\n".join(lines))
    return path


def compare_runs(run_dirs: Sequence[Path], out_dir: Path) -> Path:
    """report.md and deviations.png comparing any finished runs (folders with summary.json and trajectory.csv);
    each run is labelled by its folder and links its birdseye.png (drawn first where the run left it for later).
    A one-line UserError names a folder that is not a finished run."""
    rows = []
    for run_dir in run_dirs:
        summary_path = run_dir / "summary.json"
        if not summary_path.is_file() or not (run_dir / "trajectory.csv").is_file():
            raise UserError(f"{run_dir} is not a finished run (no summary.json and trajectory.csv)")
        summary = read_summary(summary_path)
        if summary.lane_straddle_dev_m is None:
            raise UserError(f"{summary_path}: lane_straddle_dev_m must be a number to draw the lane")
        rows.append(ReportRow(str(run_dir), run_dir, summary))
        read_trajectory(run_dir, ("t", "phys_dev"))  # a trajectory the plot cannot read is refused before writing
    if not rows:
        raise UserError("name at least one run folder to compare")
    for row in rows:  # the report links each run's birdseye.png: a run that left it for later has it drawn now
        draw_later(row.run_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return write_report(out_dir, f"{len(rows)} runs compared", rows, _differing_defense_params(rows))


def _differing_defense_params(rows: Sequence[ReportRow]) -> str:
    """One line per run with the `[defense]` parameters whose values differ between the runs."""
    params = [r.summary.defense_params or {} for r in rows]
    keys = sorted({k for p in params for k in p if len({json.dumps(q.get(k)) for q in params}) > 1})
    if not keys:
        return "The runs share every recorded [defense] parameter."
    return "[defense] parameters that differ:\n\n" + "\n".join(
        f"- {r.label}: " + ", ".join(f"{k} = {p.get(k)}" for k in keys) for r, p in zip(rows, params, strict=True))
