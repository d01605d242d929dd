"""`ld3 bound SCENARIO`: LD3's deviation bound (testbed.control.attack_bound) at the scenario's vehicle, rates, control
design and `[defense]` CUSUMs, per speed, beside the lane straddle deviation; table.md, table.csv, bound.png.

The benign residual std σ that widens b comes from `RESIDUAL_STD` (the scenario's detector) unless given.
A defense without LD3's detection has no bound here (UserError); LD3 in the paper's mode has none (inf): its
controller steers on MSF poses no detection checked and it runs no heading check.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from matplotlib.figure import Figure

from testbed.control.attack_bound import DEFAULT_HORIZON_S, Budget, deviation_bound, lateral_loop
from testbed.control.lateral import LqrLateralController
from testbed.defense.config import DefenseConfig
from testbed.defense.registry import DEFENSES
from testbed.errors import UserError
from testbed.eval.run.folder import SUMMARY, run_folder
from testbed.eval.run.scenario import Scenario
from testbed.presets import build_track, vehicle

RESIDUAL_STD: dict[str, tuple[float, float]] = {
    "oracle": (0.033, 0.0029),
    "neural": (0.041, 0.0032),
}
"""(lateral m, heading rad) root mean square of LD3's benign residuals D_MSF − D_LD and ψ_MSF − ψ_lines per
detection (their bias included), per lane detector, the larger of local and highway (docs/decisions.md, "The
deviation bound")."""
DEFAULT_K_SIGMA = 1.0
"""b_eff = b + k·σ: the attacker is granted one σ of benign residual cancelling its offset at every detection."""
DETECTION_KEYS = frozenset({"b", "tau", "heading_b", "heading_tau", "fail_closed"})
DEFAULT_SPEEDS = tuple(float(v) for v in range(5, 31, 5))


@dataclass(frozen=True)
class BoundRow:
    """One speed: the bound (free-signed attack), the one-signed attack's, the straddle deviation (m)."""

    speed: float
    bound_m: float
    one_signed_m: float
    straddle_m: float
    converged: bool
    on_car_m: float | None = None
    """The bound on the loop's responses identified on the car (`testbed.eval.search.bound_on_car`); None: not asked."""

    @property
    def margin_m(self) -> float:
        return self.straddle_m - self.bound_m


@dataclass(frozen=True)
class BoundSetting:
    """What the bound reads from a scenario: the controller, the camera period in ticks, both CUSUM budgets
    (None: paper mode, unbounded), the straddle deviation (m)."""

    controller: LqrLateralController
    every: int
    lateral: Budget | None
    heading: Budget | None
    straddle_m: float


def bound_setting(sc: Scenario, sigma: tuple[float, float] | None = None) -> BoundSetting:
    """The setting of `sc` (UserError for a defense without LD3's detection or a detector without a σ)."""
    if not DEFENSES.get(sc.defense).reads >= DETECTION_KEYS:
        raise UserError(f"the bound models LD3's detection (b, tau and the heading check); defense {sc.defense!r} "
                        f"has none: use --defense ld3 or ld3-naive-ar")
    if sigma is None:
        if sc.detector not in RESIDUAL_STD:
            raise UserError(f"no measured benign residual σ for detector {sc.detector!r} (known: "
                            f"{', '.join(RESIDUAL_STD)}): give --sigma LATERAL,HEADING")
        sigma = RESIDUAL_STD[sc.detector]
    params = vehicle(sc.vehicle)
    track = build_track(sc.track)
    lane = sc.lane if sc.lane is not None else track.ego_lane
    if not 0 <= lane < len(track.lanes):
        raise UserError(f"lane {lane} does not exist on {sc.track} ({len(track.lanes)} lanes)")
    config = DefenseConfig.from_dict(sc.defense_params)
    controller = LqrLateralController.from_vehicle(params, sc.rates.control_dt,
                                                   steer_rate_weight=sc.control.steer_rate_weight)
    every = sc.rates.camera_every
    straddle = track.lane_straddle_dev(lane, params.width)
    if not config.fail_closed:
        return BoundSetting(controller, every, None, None, straddle)
    return BoundSetting(controller, every, Budget(config.b, config.tau, sigma[0]),
                        Budget(config.heading_b, config.heading_tau, sigma[1], clamp=config.steer_yaw_tol), straddle)


def bound_rows(setting: BoundSetting, speeds: Sequence[float], k_sigma: float = DEFAULT_K_SIGMA,
               on_car: Scenario | None = None) -> list[BoundRow]:
    """The bound per speed (inf in paper mode); with `on_car`, also solved on that scenario's loop identified on
    the car at each speed."""
    rows = []
    for v in speeds:
        if v <= 0:
            raise UserError(f"speeds must be > 0 m/s, got {v:g}")
        car = None if on_car is None else bound_on_car(setting, on_car, v, k_sigma)
        if setting.lateral is None or setting.heading is None:
            rows.append(BoundRow(v, math.inf, math.inf, setting.straddle_m, True, car))
            continue
        loop = lateral_loop(setting.controller, v, setting.every)
        free = deviation_bound(loop, setting.lateral, setting.heading, k_sigma)
        signed = deviation_bound(loop, setting.lateral, setting.heading, k_sigma, one_signed=True)
        rows.append(BoundRow(v, free.bound_m, signed.bound_m, setting.straddle_m, free.converged, car))
    return rows


def bound_on_car(setting: BoundSetting, sc: Scenario, speed: float, k_sigma: float = DEFAULT_K_SIGMA) -> float:
    """The bound at `speed` on `sc`'s closed loop identified on the car (inf in paper mode, with nothing run)."""
    if setting.lateral is None or setting.heading is None:
        return math.inf
    from testbed.eval.search.bound_on_car import identify  # the simulation: loaded only to identify

    loop = identify(sc, speed, DEFAULT_HORIZON_S).loop
    return deviation_bound(loop, setting.lateral, setting.heading, k_sigma).bound_m


def _m(v: float) -> str:
    return "unbounded" if math.isinf(v) else f"{v:.3f}"


def bound_markdown(rows: Sequence[BoundRow]) -> str:
    """The rows as a markdown table (with the bound on the car where it was solved)."""
    car = any(r.on_car_m is not None for r in rows)
    lines = ["| speed (m/s) | bound (m) | one-signed (m) | " + ("on the car (m) | " if car else "")
             + "straddle (m) | margin (m) | converged |", "|---|---|---|" + ("---|" if car else "") + "---|---|---|"]
    lines += [f"| {r.speed:g} | {_m(r.bound_m)} | {_m(r.one_signed_m)} | "
              + (f"{'–' if r.on_car_m is None else _m(r.on_car_m)} | " if car else "")
              + f"{r.straddle_m:.3f} | {_m(r.margin_m)} | {'yes' if r.converged else 'no'} |" for r in rows]
    return "\n".join(lines)


def plot_bound(path: Path, rows: Sequence[BoundRow], title: str) -> None:
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    speeds = [r.speed for r in rows]
    ax.plot(speeds, [r.bound_m for r in rows], "o-", label="bound (any attack)")
    ax.plot(speeds, [r.one_signed_m for r in rows], "s--", label="bound (one-signed attack)")
    if any(r.on_car_m is not None for r in rows):
        ax.plot(speeds, [math.nan if r.on_car_m is None else r.on_car_m for r in rows], "^-.",
                label="bound on the car's identified loop")
    ax.plot(speeds, [r.straddle_m for r in rows], "r:", label="lane straddle deviation")
    ax.set_xlabel("speed (m/s)")
    ax.set_ylabel("largest |D| before the alarm (m)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def write_bound(out: Path, rows: Sequence[BoundRow], title: str, force: bool = False) -> Path:
    """table.md, table.csv, bound.png and summary.json (the rows) written into `out` all at once."""
    with run_folder(out, force) as tmp:
        (tmp / "table.md").write_text(f"# {title}\n\n{bound_markdown(rows)}\n")
        with (tmp / "table.csv").open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["speed_mps", "bound_m", "one_signed_m", "straddle_m", "margin_m", "converged",
                             "on_car_m"])
            for r in rows:
                writer.writerow([f"{r.speed:g}", f"{r.bound_m:.4f}", f"{r.one_signed_m:.4f}", f"{r.straddle_m:.4f}",
                                 f"{r.margin_m:.4f}", str(r.converged).lower(),
                                 "" if r.on_car_m is None else f"{r.on_car_m:.4f}"])
        plot_bound(tmp / "bound.png", rows, title)
        rows_json = [{k: None if isinstance(v, float) and math.isinf(v) else v
                      for k, v in {**asdict(r), "margin_m": r.margin_m}.items()} for r in rows]
        (tmp / SUMMARY).write_text(json.dumps({"title": title, "rows": rows_json}, indent=2) + "\n")
    return out / "table.md"
