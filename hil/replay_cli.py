"""`ld3 replay DRIVE`: LD3's detection (and the response's fusion as a shadow) run again over a recorded drive
(`hil.vehicle.drive_replay`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from testbed.errors import UserError

REPLAY_MARKER = "replay.csv"  # what marks a folder as an earlier replay, replaced by the next


def add_replay_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="run LD3's detection open loop over a recorded drive (run.mcap)",
                       description="Run a defense over the lane detections and localization estimates a drive "
                                   "recorded (`ld3 run ... --record` writes them to run.mcap) and write the "
                                   "D_MSF / D_LD / CUSUM table and plot.")
    p.add_argument("drive", type=Path, help="run.mcap, or the run folder holding it")
    p.add_argument("--out", type=Path, help="output folder (default: DRIVE's folder/replay)")
    p.add_argument("--track", help="the map (default: the recorded run's, from its summary.json)")
    p.add_argument("--defense", help="defense to run (default: the recorded run's, else ld3)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="defense.KEY=VALUE",
                   help="a [defense] parameter over the recorded run's, e.g. defense.tau=1.5")
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace) -> int:
    import tomllib

    from hil.vehicle.drive_replay import drive_settings, replay_drive, write_replay
    from testbed.defense.registry import declared_table
    from testbed.eval.run.folder import check_out_dir, output_folder

    path = args.drive / "run.mcap" if args.drive.is_dir() else args.drive
    if not path.is_file():
        raise FileNotFoundError(f"no recorded drive at {path}")
    out = args.out or path.parent / "replay"
    check_out_dir(out, True, REPLAY_MARKER, "a replay")
    settings = drive_settings(path)
    track = args.track or settings.get("track")
    if track is None:
        raise UserError(f"{path} has no summary.json beside it: give --track")
    defense = args.defense or settings.get("defense") or "ld3"
    params = declared_table(defense, settings.get("defense_params") or {})
    for item in args.overrides:
        key, sep, value = item.partition("=")
        if not sep or not key.startswith("defense."):
            raise UserError(f"--set takes defense.KEY=VALUE, got {item!r}")
        params[key.removeprefix("defense.")] = tomllib.loads(f"v = {value}")["v"]
    result = replay_drive(path, track, defense, params)
    with output_folder(out, force=True, marker=REPLAY_MARKER, what="a replay") as tmp:
        written = write_replay(tmp, result, f"replay of {path} · {track} · {defense}")
    t = result.detection_time_s
    verdict = f"detects at {t:.2f} s" if t is not None else "never alarms"
    print(f"{path}: {len(result.rows)} camera frames, {defense} {verdict}; "
          f"{', '.join(written)} in {out}")
    return 0
