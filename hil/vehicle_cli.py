"""`ld3 vehicle`: the loop on a real vehicle (`hil.vehicle.run`). Exit codes as `ld3 hil`: 0 done, 2 usage (and a
sensor that never delivered a first GNSS fix), 3 the run ended on a fault (outputs written), 4 the CAN link
failed."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from hil.link.errors import LINK_ERRORS, link_error_line
from hil.link.profile import DEFAULT_PROFILE
from hil.link.scheduling import RT_PRIORITY
from hil.vehicle.geodetic import DEFAULT_ORIGIN, parse_origin
from testbed.eval.run.folder import claimed_out_dir
from vehicles.params import get_vehicle

EXIT_FAULT, EXIT_LINK = 3, 4


def add_vehicle_parser(sub: argparse._SubParsersAction, add_bus_arguments, bus_from_args) -> None:
    """Add `ld3 vehicle`; the bus arguments are those of `ld3 hil`."""
    from testbed.defense.registry import DEFENSES
    from testbed.perception.detectors.registry import DETECTORS

    p = sub.add_parser("vehicle", help="run the detection/response loop on a real vehicle (no simulator)",
                       description="Drive a real chassis over CAN with GNSS from an NMEA stream, frames from a "
                                   "camera and the map of a track preset placed at --origin. Ctrl-C brakes to "
                                   "standstill in lane and ends the run with its outputs.")
    p.add_argument("--map", required=True, help="track preset NAME[@SEED] whose lanes the vehicle drives")
    p.add_argument("--origin", default=",".join(map(str, DEFAULT_ORIGIN)), metavar="LAT,LON",
                   help="latitude and longitude (degrees) of the map's origin (default %(default)s)")
    p.add_argument("--gnss", required=True, metavar="nmea:PATH", help="NMEA 0183 stream: serial device, pty or file")
    p.add_argument("--camera", metavar="v4l2:/dev/videoN|video:PATH", help="camera device or video file (OpenCV)")
    p.add_argument("--calibration", type=Path, help="camera calibration TOML (intrinsics, distortion, mount)")
    p.add_argument("--detector", default="neural", choices=DETECTORS.names(), metavar="NAME",
                   help="lane detector reading the camera (default neural; none without a camera)")
    p.add_argument("--detector-weights", metavar="PATH", help="the detector's weights; for neural-onnx a detector "
                   "graph from `ld3 ld export-onnx` runs without torch or OpenCV")
    p.add_argument("--defense", choices=DEFENSES.names(), metavar="NAME",
                   help="default: the --scenario's [defense] kind, else ld3")
    p.add_argument("--vehicle", default="dev-chassis", help="vehicle parameter set (default dev-chassis)")
    p.add_argument("--speed", type=float, default=2.0, help="target speed, m/s (default 2)")
    p.add_argument("--duration", type=float, default=60.0, help="seconds to drive (default 60)")
    p.add_argument("--lane", type=int, help="lane to drive (default: the one the first fix lies in)")
    p.add_argument("--profile", default=DEFAULT_PROFILE, help="chassis profile: shipped name or folder")
    p.add_argument("--scenario", type=Path, metavar="FILE", help="a scenario TOML whose [rates], [control] and "
                   "[defense] tables the loop runs with (its other keys are the simulator's and are not read)")
    p.add_argument("--record", action="store_true", help="also write run.mcap (what LD3's detection read at each "
                   "frame) for `ld3 replay`")
    p.add_argument("--rt-priority", type=int, default=RT_PRIORITY, metavar="N",
                   help="SCHED_FIFO priority of the run's threads, the command pacer one above (default %(default)s; "
                        "0: normal scheduling; without the privilege the run goes on at normal priority and its "
                        "summary says so)")
    p.add_argument("--out", type=Path, help="output folder (default runs/vehicle-DATE-TIME)")
    p.add_argument("--force", action="store_true", help="replace a finished drive already in --out")
    add_bus_arguments(p, "the chassis's CAN interface (hardware rules unless the virtual bus or a pty)")
    p.set_defaults(func=lambda args: cmd_vehicle(args, bus_from_args))


def cmd_vehicle(args: argparse.Namespace, bus_from_args) -> int:
    from hil.vehicle.run import VehicleConfig, VehicleRun
    from hil.vehicle.scenario import loop_tables

    tables = loop_tables(args.scenario) if args.scenario is not None else {}
    defense = args.defense or tables.pop("defense", None) or "ld3"
    tables.pop("defense", None)
    config = VehicleConfig(map=args.map, origin=parse_origin(args.origin), gnss=args.gnss, camera=args.camera,
                           calibration=args.calibration, detector=args.detector,
                           detector_weights=args.detector_weights, defense=defense,
                           vehicle=args.vehicle, speed=args.speed, duration=args.duration, lane=args.lane,
                           profile=args.profile, record=args.record, rt_priority=args.rt_priority, **tables)
    if args.out is None:
        args.out = Path("runs") / f"vehicle-{time.strftime('%Y%m%d-%H%M%S')}"
    try:
        with claimed_out_dir(args.out, args.force):  # an earlier drive comes back if this one fails to finish
            run = VehicleRun(config, bus_from_args(args), args.out)
            try:
                summary = run.run()
            finally:
                run.close()
    except LINK_ERRORS as exc:
        print(link_error_line(exc), file=sys.stderr)
        return EXIT_LINK
    print(f"vehicle on {config.map}: consequence {summary['consequence']}, {summary['sim_time_s']:.1f} s, "
          f"detected {summary['detected']}; {summary['nmea_fixes']} GNSS fixes, {summary['camera_frames']} frames; "
          f"outputs in {args.out}")
    bias = summary["odometry_bias_rad_per_m"]
    if bias is not None:
        offset = math.degrees(math.atan(bias * get_vehicle(config.vehicle).wheelbase))
        print(f"odometry: yaw rate {bias:+.5f} rad/m off, a steering-angle offset of {offset:+.2f}° if the chassis "
              f"derives it from its steering")
    if summary["faults"]:
        first = summary["faults"][0]
        print(f"ld3: chassis fault: {first['kind']} at {first['time']:.2f} s ({first['detail']}); outputs in "
              f"{args.out}", file=sys.stderr)
        return EXIT_FAULT
    return 0
