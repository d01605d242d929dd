"""`ld3 control report`: the lateral loop of shipped vehicles over speeds and control rates, on each car model of
`testbed.eval.analysis.lateral_loop`: margins.csv (every speed), margins.md (the worst speed of each vehicle, rate and
model against the floors), summary.json, and per vehicle and rate the margins against speed, the closed-loop
poles, and the step and lane-change responses (PNG)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.control.lateral_model import LateralModel
from testbed.errors import UserError
from testbed.eval.analysis.lateral_loop import (
    CAR_MODELS,
    FLOORED,
    MIN_GAIN_MARGIN_DB,
    MIN_PHASE_MARGIN_DEG,
    LateralLoop,
    LoopPoint,
    lane_change_offset,
    step_offset,
)
from testbed.eval.run.folder import SUMMARY, run_folder
from testbed.rates import PHYSICS_HZ
from vehicles.params import VEHICLES, vehicle_names

SPEEDS = tuple(float(v) for v in range(1, 41))
RESPONSE_SPEEDS = (5.0, 27.0)
FIELDS = ("vehicle", "rate_hz", "model", "speed", "max_pole", "gain_up_db", "gain_down_db", "phase_deg",
          "crossover_hz", "meets_floor")


def _row(vehicle: str, hz: float, model: str, p: LoopPoint) -> dict[str, object]:
    return {"vehicle": vehicle, "rate_hz": f"{hz:g}", "model": model, "speed": f"{p.speed:g}",
            "max_pole": f"{p.max_pole:.4f}", "gain_up_db": f"{p.gain_up_db:.2f}",
            "gain_down_db": f"{p.gain_down_db:.2f}", "phase_deg": f"{p.phase_deg:.1f}",
            "crossover_hz": f"{p.crossover_hz:.2f}", "meets_floor": p.meets()}


def _worst(points: list[LoopPoint]) -> str:
    """One table cell: the largest pole, the smallest margins, and the speeds they occur at."""
    pole = max(points, key=lambda p: p.max_pole)
    gain = min(points, key=lambda p: min(p.gain_up_db, p.gain_down_db))
    phase = min(points, key=lambda p: p.phase_deg)
    verdict = "ok" if all(p.meets() for p in points) else ("**unstable**" if pole.max_pole >= 1.0 else "**thin**")
    return (f"{verdict}: \\|p\\| {pole.max_pole:.3f} ({pole.speed:g}), GM {min(gain.gain_up_db, gain.gain_down_db):.1f}"
            f" dB ({gain.speed:g}), PM {phase.phase_deg:.0f}° ({phase.speed:g})")


def _plot_margins(path: Path, title: str, by_model: dict[str, list[LoopPoint]]) -> None:
    fig = Figure(figsize=(10, 7))
    axes = fig.subplots(3, 1, sharex=True)
    for name, points in by_model.items():
        v = [p.speed for p in points]
        axes[0].plot(v, [p.max_pole for p in points], label=name)
        axes[1].plot(v, [min(p.gain_up_db, p.gain_down_db, 60.0) for p in points], label=name)
        axes[2].plot(v, [min(p.phase_deg, 180.0) for p in points], label=name)
    axes[0].axhline(1.0, color="k", lw=0.8)
    axes[1].axhline(MIN_GAIN_MARGIN_DB, color="k", lw=0.8, ls="--")
    axes[2].axhline(MIN_PHASE_MARGIN_DEG, color="k", lw=0.8, ls="--")
    for ax, label in zip(axes, ("largest |closed-loop pole|", "gain margin (dB)", "phase margin (°)"), strict=True):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].set_xlabel("speed (m/s)")
    fig.suptitle(title)
    fig.savefig(path, dpi=90)


def _plot_poles(path: Path, title: str, loops: dict[str, LateralLoop]) -> None:
    fig = Figure(figsize=(6, 6))
    ax = fig.subplots()
    circle = np.exp(1j * np.linspace(0, 2 * math.pi, 200))
    ax.plot(circle.real, circle.imag, "k", lw=0.8)
    for name, loop in loops.items():
        poles = np.concatenate([loop.closed_loop(v).poles() for v in SPEEDS[::3]])
        ax.plot(poles.real, poles.imag, ".", ms=3, label=name)
    ax.set_aspect("equal")
    ax.set_xlim(-1.6, 1.6)
    ax.set_ylim(-1.6, 1.6)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.savefig(path, dpi=90)


def _plot_responses(path: Path, title: str, loops: dict[str, LateralLoop]) -> None:
    fig = Figure(figsize=(11, 7))
    axes = fig.subplots(2, 2, sharex="col")
    for col, (label, make) in enumerate((("0.5 m step", step_offset), ("3.5 m lane change", lane_change_offset))):
        for name, loop in loops.items():
            for v in RESPONSE_SPEEDS:
                t, err, steer = loop.response(v, make(loop.dt))
                axes[0, col].plot(t, np.clip(err, -4, 4), label=f"{name}, {v:g} m/s")
                axes[1, col].plot(t, np.degrees(np.clip(steer, -1, 1)))
        axes[0, col].set_title(label)
        axes[0, col].set_ylabel("lateral error (m)")
        axes[1, col].set_ylabel("steering command (°)")
        axes[1, col].set_xlabel("t (s)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title)
    fig.savefig(path, dpi=90)


def write_control_report(out: Path, vehicles: list[str], rates: list[float], weight: float,
                         force: bool = False) -> dict[str, object]:
    """Analyse every vehicle × rate × car model over `SPEEDS` and write the report folder; its summary."""
    unknown = [v for v in vehicles if v not in VEHICLES]
    if unknown:
        raise UserError(f"unknown vehicle {unknown[0]!r}; choose from {', '.join(vehicle_names())}")
    bad = [hz for hz in rates if not (math.isfinite(hz) and 1.0 <= hz <= 1000.0)]
    if bad:
        raise UserError(f"--rates: {bad[0]:g} Hz is not a control rate; give rates between 1 and 1000 Hz")
    rows: list[dict[str, object]] = []
    table = ["| vehicle | rate (Hz) | " + " | ".join(m.name for m in CAR_MODELS) + " |",
             "|---|---|" + "---|" * len(CAR_MODELS)]
    failing: list[str] = []
    with run_folder(out, force) as tmp:
        for name in vehicles:
            params = VEHICLES[name]
            design = LateralModel.from_vehicle(params)
            for hz in rates:
                loops = {m.name: LateralLoop(design, params.max_steer, hz, weight, m, PHYSICS_HZ) for m in CAR_MODELS}
                by_model = {m: [loop.point(v) for v in SPEEDS] for m, loop in loops.items()}
                for m, points in by_model.items():
                    rows += [_row(name, hz, m, p) for p in points]
                    driven = [p for p in points if p.speed <= max(params.max_speed, 1.0)]
                    if m in {f.name for f in FLOORED} and not all(p.meets() for p in driven):
                        failing.append(f"{name} {hz:g} Hz {m}")
                table.append(f"| {name} | {hz:g} | " + " | ".join(_worst(p) for p in by_model.values()) + " |")
                stem = f"{name}-{hz:g}hz"
                title = f"{name}, {hz:g} Hz, steering-rate weight {weight:g}"
                _plot_margins(tmp / f"{stem}-margins.png", title, by_model)
                _plot_poles(tmp / f"{stem}-poles.png", title, loops)
                _plot_responses(tmp / f"{stem}-responses.png", title, loops)
        with (tmp / "margins.csv").open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
        head = (f"Lateral loop, steering-rate weight {weight:g}, speeds {SPEEDS[0]:g}–{SPEEDS[-1]:g} m/s: the worst "
                f"speed of each (largest closed-loop pole, smallest gain margin up or down, smallest phase margin, "
                f"speed in m/s). Floors: {MIN_GAIN_MARGIN_DB:g} dB, {MIN_PHASE_MARGIN_DEG:g}°, on "
                f"{', '.join(m.name for m in FLOORED)} up to the vehicle's top speed.")
        (tmp / "margins.md").write_text(head + "\n\n" + "\n".join(table) + "\n")
        summary = {"vehicles": vehicles, "rates_hz": rates, "steer_rate_weight": weight, "models":
                   [m.name for m in CAR_MODELS], "floors": {"gain_db": MIN_GAIN_MARGIN_DB,
                                                            "phase_deg": MIN_PHASE_MARGIN_DEG},
                   "below_floor": failing}
        (tmp / SUMMARY).write_text(json.dumps(summary, indent=1) + "\n")
    return summary
