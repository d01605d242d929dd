"""`ld3 campaign maps --maps DIR|FILE…`: every OpenDRIVE file's default route driven with LD3 at a cruise speed
of CRUISE (the planner slows for curves): benign with the oracle and with the campaign's lane detector, and once
under the default trace injection; a table per file. A file the reader refuses gets no runs and its one line in
the table; a route too short to detect the attack and stop before the run's end gets no attacked drive, and its
table says the length it would need."""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path

from testbed.control.planner import AR_DECEL, CRUISE_ACCEL
from testbed.errors import UserError
from testbed.eval.campaign.driver import CampaignRun
from testbed.eval.run.scenario import END_MARGIN_M, load_scenario
from testbed.eval.run.summary import RunSummary
from testbed.presets import TrackFileError, build_track

CRUISE = 15.0  # m/s
SLOWER = 1.6  # the simulated time allowed over the route's length at the cruise speed (curves, start, stop)
ATTACK_AT = 10.0  # s: the trace injection's start, or a third of the route's time at the cruise speed on short routes
DETECT_WITHIN = 6.1
"""s from the trace injection's start to LD3's alarm that an attacked drive is given room for: the slowest this
campaign measured on the CARLA towns and esmini files (6.05 s, neural; the oracle's 5.15-5.32 s)."""


def attack_start_s(route_m: float) -> float:
    """The trace injection's start on a route of `route_m`: ATTACK_AT, or a third of its time on short routes."""
    return round(min(ATTACK_AT, route_m / CRUISE * SLOWER / 3.0), 2)


def _stopped_at(attack_s: float, start_s: float) -> float:
    """The route length (m) the car uses when the attack starts at `attack_s`: from `start_s`, ramping from rest to
    CRUISE, alarmed DETECT_WITHIN after the attack's start, stopped at the response's AR_DECEL, and the last
    END_MARGIN_M where a run ends."""
    alarm = attack_s + DETECT_WITHIN
    ramp = CRUISE / CRUISE_ACCEL
    speed = min(CRUISE, CRUISE_ACCEL * alarm)
    driven = 0.5 * CRUISE_ACCEL * min(alarm, ramp) ** 2 + CRUISE * max(0.0, alarm - ramp)
    return start_s + driven + speed**2 / (2.0 * AR_DECEL) + END_MARGIN_M


def attacked_route_m(start_s: float) -> float:
    """The shortest route (m) on which an attacked drive fits, its attack starting at `attack_start_s` of that
    route (a fixed point: a longer route starts the attack later, by less than it adds)."""
    route = 0.0
    while (longer := _stopped_at(attack_start_s(route), start_s)) > route + 0.01:
        route = longer
    return longer


def map_files(maps: Sequence[str]) -> list[Path]:
    """The .xodr files named: each FILE, and every `*.xodr` in each DIR (sorted); UserError for anything else."""
    files: list[Path] = []
    for name in maps:
        path = Path(name)
        if path.is_dir():
            found = sorted(path.glob("*.xodr"))
            if not found:
                raise UserError(f"--maps {name}: no .xodr file in the folder")
            files += found
        elif path.is_file():
            files.append(path)
        else:
            raise UserError(f"--maps {name}: no such file or folder")
    return files


def map_runs(detector: str, maps: Sequence[str]) -> list[CampaignRun]:
    """Per file, its default route: benign LD3 with the oracle and with `detector`, and attacked with `detector`
    (runs `FILE-benign-oracle`, `FILE-benign-DETECTOR`, `FILE-attacked-DETECTOR`); on a route shorter than
    `attacked_route_m` no attacked run, and the benign runs' tag `too_short` says why."""
    runs = []
    base = load_scenario("local")
    for path in map_files(maps):
        spec = f"xodr:{path}"
        try:
            track = build_track(spec)
        except TrackFileError as exc:
            print(f"maps: {exc}", file=sys.stderr)
            continue
        travel = track.length / CRUISE * SLOWER
        duration = round(travel + 10.0)
        drive = base.with_overrides(track=spec, speed=CRUISE, duration=float(duration), localization="msf",
                                    defense="ld3", lane=None, name=f"maps-{path.stem}")
        trace = {"kind": "trace", "trace": "default", "start": attack_start_s(track.length)}
        drives = [("benign", det, None) for det in dict.fromkeys(("oracle", detector))]
        needs = attacked_route_m(drive.start_s)
        short = {"too_short": f"too short for an attacked drive at {CRUISE:g} m/s: needs {math.ceil(needs)} m"
                 } if track.length < needs else {}
        if not short:
            drives.append(("attacked", detector, trace))
        for kind, det, attack in drives:
            tags = {"file": path.name, "kind": kind, "detector": det, "route_m": round(track.length), **short}
            if attack is not None:
                tags["attack_s"] = attack["start"]
            runs.append(CampaignRun(f"{path.stem}-{kind}-{det}", drive.with_overrides(detector=det, attack=attack),
                                    tags))
    return runs


def map_table(done: list[tuple[CampaignRun, RunSummary]], out: Path) -> str:
    """One table per file: each drive's consequence, alarm (and the check that raised it), largest |D| and how it
    ended; benign drives must reach the route's end without an alarm, attacked ones stop in lane on an alarm raised
    after the attack's start (an earlier one is a false alarm, marked "before the attack"); a route too short for an
    attacked drive says so in its place, judged neither way."""
    by_file: dict[str, list[tuple[CampaignRun, RunSummary]]] = {}
    for run, s in done:
        by_file.setdefault(run.tags["file"], []).append((run, s))
    lines = [f"Cruise speed {CRUISE:g} m/s; pass: benign reaches the route's end with no alarm, attacked stops in "
             "lane."]
    for name, items in by_file.items():
        lines += ["", f"### {name} (default route, {items[0][0].tags['route_m']} m)", "",
                  "| drive | detector | consequence | alarm | max abs dev (m) | simulated (s) | pass |",
                  "|---|---|---|---|---|---|---|"]
        for run, s in items:
            want = "reach_destination" if run.tags["kind"] == "benign" else "stop_in_lane"
            early = s.detected and s.detection_time_s < run.tags.get("attack_s", 0.0)
            ok = s.consequence == want and not early and (run.tags["kind"] == "attacked" or not s.detected)
            alarm = f"{s.detection_time_s:.2f} s" if s.detected else "none"
            alarm += f", {s.alarm_check}" if s.detected and s.alarm_check is not None else ""
            alarm += " (before the attack)" if early else ""
            lines.append(f"| {run.tags['kind']} | {run.tags['detector']} | {s.consequence} | {alarm} "
                         f"| {s.max_abs_dev_m:.3f} | {s.sim_time_s:.1f} | {'yes' if ok else 'NO'} |")
        if "too_short" in items[0][0].tags:
            lines.append(f"| attacked | {items[-1][0].tags['detector']} | {items[0][0].tags['too_short']} "
                         "| | | | not judged |")
    return "\n".join(lines)
