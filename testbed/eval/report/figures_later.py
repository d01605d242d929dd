"""`ld3 figures`: the figures of runs that left them for later (believed.csv, no birdseye.png), drawn from their
folders: the track, the attack and the defense rebuilt from the summary's resolved scenario (the run built, never
stepped), the rows, the believed path and the traffic read back; the same picture as at the run's end up to
trajectory.csv's rounding.
"""

from __future__ import annotations

from pathlib import Path

from testbed.defense.registry import declared_table
from testbed.errors import UserError
from testbed.eval.run.figures import (
    BELIEVED,
    BIRDSEYE,
    FigureInputs,
    fusion_title,
    read_believed,
    read_rows,
    read_traffic,
    save_run_figures,
)
from testbed.eval.run.runner import SimRun
from testbed.eval.run.scenario import Scenario
from testbed.eval.run.summary import read_summary


def run_folders(root: Path) -> list[Path]:
    """`root` itself when it is a run folder (summary.json and trajectory.csv), else every run folder under it;
    a one-line UserError when there are none."""
    if not root.is_dir():
        raise UserError(f"{root} is not a folder; name a run folder or a campaign or search folder")
    found = sorted(p.parent for p in root.rglob("summary.json") if (p.parent / "trajectory.csv").is_file()
                   and not any(part.startswith(".") for part in p.parent.relative_to(root).parts))
    if not found:
        raise UserError(f"{root} holds no run folder (summary.json beside trajectory.csv)")
    return found


def draw_later(run_dir: Path) -> bool:
    """Draw the figures of a run folder whose run deferred them (believed.csv, no birdseye.png) from its files;
    False (nothing drawn) for any other folder."""
    if (run_dir / BIRDSEYE).exists() or not (run_dir / BELIEVED).exists():
        return False
    summary = read_summary(run_dir / "summary.json")
    try:
        resolved = dict(summary.resolved_scenario)
        resolved["defense_params"] = declared_table(resolved["defense"], resolved["defense_params"])
        sc = Scenario.model_validate(resolved)
    except (ValueError, TypeError, KeyError, AttributeError) as exc:
        why = " ".join(str(exc).split())[:200]
        raise UserError(f"{run_dir}/summary.json holds no scenario to draw the figures of ({type(exc).__name__}: "
                        f"{why})") from None
    sim = SimRun(sc)  # builds the painted track, the attack and the defense; never steps
    try:
        parts = sim.parts
        traffic = run_dir / "traffic.csv"
        inputs = FigureInputs(
            parts.track, parts.lane_width, summary.lane_straddle_dev_m, read_believed(run_dir / BELIEVED),
            summary.detection_time_s, summary.stop_time_s,
            f"{sc.name} · {sc.track} · defense {sc.defense} · {summary.consequence}",
            fusion_title=fusion_title(sc.name, sc.track, parts.attack),
            attack_t=parts.attack.start_time if parts.attack is not None else None,
            threshold=parts.defense.alarm_threshold,
            traffic=read_traffic(traffic) if traffic.exists() else None,
            traffic_size=(parts.traffic.length, parts.traffic.width) if parts.traffic is not None else (0.0, 0.0))
    finally:
        sim.close()
    save_run_figures(run_dir, read_rows(run_dir), inputs)
    return True
