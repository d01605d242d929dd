"""`ld3 control report`'s arguments; the analysis (python-control, matplotlib) is imported when it runs, so
building `ld3 --help` imports neither."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from testbed.control.config import ControlConfig
from testbed.errors import UserError
from vehicles.params import vehicle_names

DEFAULT_RATES = (20.0, 40.0, 50.0, 100.0)


def add_control_parser(subparsers) -> argparse.ArgumentParser:
    """Register `ld3 control report`."""
    control = subparsers.add_parser("control", help="the lateral controller's design: margins, poles, responses")
    sub = control.add_subparsers(dest="control_cmd", required=True)
    p = sub.add_parser("report", help="closed-loop poles, gain and phase margins, step and lane-change responses "
                                      "over 1–40 m/s, per vehicle, control rate and car model")
    p.add_argument("--vehicle", action="append", help=f"vehicle (repeatable; default all: "
                   f"{', '.join(vehicle_names())})")
    p.add_argument("--rates", default=",".join(f"{hz:g}" for hz in DEFAULT_RATES),
                   help="control rates in Hz, comma-separated (default %(default)s)")
    p.add_argument("--steer-rate-weight", type=float, default=ControlConfig().steer_rate_weight,
                   help="the [control] steer_rate_weight to analyse (default: the shipped %(default)g)")
    p.add_argument("--out", type=Path, required=True, help="report folder (written whole, or not at all)")
    p.add_argument("--force", action="store_true", help="replace an earlier report in --out")
    p.set_defaults(func=cmd_control_report)
    return control


def cmd_control_report(args: argparse.Namespace) -> int:
    try:
        rates = [float(r) for r in args.rates.split(",") if r.strip()]
    except ValueError:
        raise UserError(f"--rates {args.rates!r}: give control rates in Hz, comma-separated, e.g. 40,50,100") from None
    if not rates:
        raise UserError("--rates: give at least one control rate in Hz")
    if not (math.isfinite(args.steer_rate_weight) and args.steer_rate_weight >= 0.0):
        raise UserError(f"--steer-rate-weight {args.steer_rate_weight:g}: give a weight of 0 or more")
    from testbed.eval.analysis.control_report import write_control_report

    summary = write_control_report(args.out, args.vehicle or vehicle_names(), rates, args.steer_rate_weight,
                                   args.force)
    print((args.out / "margins.md").read_text(), end="")
    below = summary["below_floor"]
    print(f"below the floors: {', '.join(below)}" if below else "every floored model meets the floors")
    print(f"report: {args.out}")
    return 0
