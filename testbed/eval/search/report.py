"""The report of a worst-case attack search: report.md with the best attack, the best per family, a replay
command, and convergence.png (each trial's deviation before detection and the best score so far)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from testbed.attacks.threat import reaches_lines, threat_label
from testbed.errors import UserError
from testbed.eval.run.scenario import Scenario
from testbed.eval.search.attack_search import AttackSearch, TrialOutcome, attack_spec, in_threat_model_note
from testbed.eval.search.bound_table import BoundRow, bound_rows, bound_setting


def _f(v: float | None) -> str:
    return "–" if v is None else "unbounded" if math.isinf(v) else f"{v:.2f}"


def plot_convergence(path: Path, outcomes: Sequence[TrialOutcome], straddle: float | None, title: str) -> None:
    """Per-trial deviation before detection by family, the best score so far, the lane straddle line."""
    fig = Figure(figsize=(9, 4.5))
    ax = fig.add_subplot()
    scored = [o for o in outcomes if o.score is not None]
    for family in sorted({o.family for o in scored}):
        pts = [(o.number, o.dev_before_m) for o in scored if o.family == family]
        ax.scatter(*zip(*pts, strict=True), s=14, label=family)
    if scored:
        n = np.array([o.number for o in scored])
        best = np.maximum.accumulate(np.array([o.score for o in scored]))
        ax.step(n, best, where="post", color="k", lw=1.5, label="best score so far (m; + 1 for an undetected crash)")
    if straddle is not None:
        ax.axhline(straddle, color="r", ls="--", lw=1, label="lane straddle deviation")
    ax.set_xlabel("trial")
    ax.set_ylabel("|D| before detection (m)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def search_bound(victim: Scenario) -> BoundRow | str:
    """LD3's deviation bound at the victim's speed (testbed.eval.search.bound_table), or why there is none: what
    the report's bound section shows, solved apart from it (`ld3 search` solves it while the trials run)."""
    try:
        return bound_rows(bound_setting(victim), [victim.speed])[0]
    except UserError as exc:
        return str(exc)


def bound_section(search: AttackSearch, outcomes: Sequence[TrialOutcome], row: BoundRow | str | None = None,
                  ) -> list[str]:
    """"Bound at the same settings": LD3's deviation bound at the victim's speed (`row`, solved here when None)
    beside the search's worst |D| before detection."""
    victim = search.spec.victim
    lines = ["## Bound at the same settings", ""]
    if row is None:
        row = search_bound(victim)
    if isinstance(row, str):
        return [*lines, f"No bound: {row}.", ""]
    worst = max((o.dev_before_m for o in outcomes if o.dev_before_m is not None), default=None)
    bound = "unbounded (paper mode)" if math.isinf(row.bound_m) else f"{row.bound_m:.3f} m"
    lines.append(f"Largest |D| before the alarm at {victim.speed:g} m/s (`ld3 bound`): {bound}; one-signed attacks "
                 f"{_f(row.one_signed_m)} m; lane straddle deviation {row.straddle_m:.3f} m. Worst |D| before "
                 f"detection found here: {_f(worst)} m"
                 + ("" if not reaches_lines(search.spec.threat) else
                    " (the bound covers the localization only; this threat model reaches the lines)") + ".")
    return [*lines, ""]


def write_search_report(search: AttackSearch, bound: BoundRow | str | None = None) -> Path:
    """report.md and convergence.png in the search folder; best.toml beside them. `bound` is `search_bound`'s
    answer when already solved."""
    spec, out = search.spec, search.out
    outcomes = search.sorted_outcomes()
    best = search.best()
    best_path = search.write_best()
    straddle = next((o.straddle_m for o in outcomes if o.straddle_m is not None), None)
    victim = spec.victim
    title = f"search: {victim.track}, defense {victim.defense}, threat {threat_label(spec.threat)}"
    plot_convergence(out / "convergence.png", outcomes, straddle, title)
    failed = sum(o.score is None for o in outcomes)
    undetected = [o for o in outcomes if o.undetected_departure]
    lines = [
        f"# Worst-case attack search: {victim.name} on {victim.track}",
        "",
        f"Victim: defense `{victim.defense}` {victim.defense_params or ''}, detector `{victim.detector}`, "
        f"localization `{victim.localization}`, speed {victim.speed} m/s, seed {victim.seed}.",
        f"{in_threat_model_note(spec.threat)}. Families searched: "
        f"{', '.join(f'`{c.name}`' for c in search.families)}. Objective: `{spec.objective}`; "
        f"{len(outcomes)} trials ({failed} failed runs), sampler seed {spec.seed}.",
        "",
    ]
    if best is not None:
        lines += [
            "## Worst attack found",
            "",
            f"`{attack_spec(best.attack)}` (trial {best.number}): detected {best.detected}"
            + (f" at {best.detection_time_s:.2f} s" if best.detection_time_s is not None else "")
            + f", |D| before detection {_f(best.dev_before_m)} m, max |D| {_f(best.max_dev_m)} m, "
              f"consequence `{best.consequence}` (lane straddle deviation {_f(straddle)} m).",
            "",
            f"Replay: `ld3 run {best_path}`",
            "",
            f"Losses (a departure or contact of any kind, detected or not): {sum(bool(o.loss) for o in outcomes)} "
            f"of {len(outcomes)} trials; undetected lane departures (|D| before detection ≥ the straddle "
            f"deviation): {len(undetected)}.",
            "",
        ]
    lines += bound_section(search, outcomes, bound)
    lines += ["## Best per family", "", "| family | trials | losses | attack | detected | "
              "\\|D\\| before detection (m) | max \\|D\\| (m) | consequence |", "|---|---|---|---|---|---|---|---|"]
    for family in sorted({o.family for o in outcomes}):
        mine = [o for o in outcomes if o.family == family]
        top = max((o for o in mine if o.score is not None), key=lambda o: o.score, default=None)
        if top is None:
            lines.append(f"| `{family}` | {len(mine)} | – | – | – | – | – | all runs failed |")
            continue
        losses = sum(bool(o.loss) for o in mine)
        lines.append(f"| `{family}` | {len(mine)} | {losses} | `{attack_spec(top.attack)}` | {top.detected} | "
                     f"{_f(top.dev_before_m)} | {_f(top.max_dev_m)} | {top.consequence} |")
    lines += ["", "![convergence](convergence.png)", "",
              "Every trial: trials.csv; its run folder: trials/trial-NNNN/."]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
