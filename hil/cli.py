"""Command line of the CAN link: `ld3 hil SCENARIO` (a scenario over CAN), `ld3 hil replay LOG` (play a log onto a
bus) and `ld3 ecu` (the ECU emulator); `python -m hil ecu|replay ...` runs the last two without the ld3 command.

An ECU plant is named by `--plant`: "kinematic" (hil.emulator.kinematic_plant), "pybullet"
(hil.emulator.plants.pybullet_plant, the scenario's PyBullet car) or "package.module:factory", called with the
`--plant-arg KEY=VALUE` pairs as keyword strings and returning a ChassisPort; `--scenario NAME` selects the
PyBullet car of that scenario.
`--profile NAME|PATH` picks the chassis protocol of both commands (hil.link.profile).

Exit codes: 0 done; 2 a usage error; 3 the run ended on a chassis fault (the car braked to standstill in lane;
outputs written); 4 the CAN link failed (no such interface or device, the ECU process or handshake failed).
Each failure is one line on stderr.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import math
import signal
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import can

from hil.detect_cli import add_detect_parser, add_labels_arguments
from hil.emulator.ecu import EcuEmulator, EcuLimits
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.emulator.log_replay import replay_log
from hil.link.bus_config import BusConfig, interfaces, parse_options
from hil.link.ecu_process import READY_PREFIX
from hil.link.errors import LINK_ERRORS, link_error_line
from hil.link.profile import DEFAULT_PROFILE, load_profile
from hil.link.secoc_key import link_key
from hil.link.slcan_pty import SlcanPtyBus
from hil.link.timing import ClockMode
from hil.replay_cli import add_replay_parser
from hil.vehicle_cli import add_vehicle_parser
from testbed.chassis import ChassisPort
from testbed.cli import OneLineParser, positive, seconds
from testbed.errors import UserError
from testbed.eval.run.folder import check_out_dir
from testbed.eval.run.outputs import chassis_faults
from testbed.extras import require_modules

PlantFactory = Callable[..., ChassisPort]
REPLAY = "replay"
POSITIVE_PLANT_ARGS = frozenset({"wheelbase", "substep"})  # the kinematic plant's lengths and steps
EXIT_USAGE, EXIT_CHASSIS_FAULT, EXIT_LINK = 2, 3, 4


def resolve_plant(spec: str) -> PlantFactory:
    """"kinematic", "pybullet" or "package.module:callable" -> a factory of ChassisPort."""
    if spec == "kinematic":
        return KinematicBicyclePlant
    if spec == "pybullet":
        spec = "hil.emulator.plants:pybullet_plant"
    module_name, _, attribute = spec.partition(":")
    if not attribute:
        raise UserError(f"plant must be 'kinematic', 'pybullet' or 'package.module:factory', got {spec!r}")
    try:
        return getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as exc:
        raise UserError(f"cannot load plant {spec!r}: {exc}") from None


# ---------------------------------------------------------------------- bus
def add_bus_arguments(parser: argparse.ArgumentParser, interface_help: str, *extra: str) -> None:
    """--interface (any python-can interface, and `extra` names), --channel, --bitrate, --can-option and
    --can-config (a section of python-can's configuration file)."""
    parser.add_argument("--interface", choices=(*interfaces(), *extra), default="virtual", metavar="NAME",
                        help=f"{interface_help}; any python-can interface: {', '.join((*interfaces(), *extra))}")
    parser.add_argument("--channel", default=None,
                        help="virtual channel name, serial path, netdev or adapter channel (default: python-can's "
                             "configuration, CAN_CHANNEL or ~/.canrc, where it names the same interface)")
    parser.add_argument("--bitrate", type=int, default=None, help="bit/s (default: python-can's configuration, "
                                                                  "else 500000 where the interface sets one)")
    parser.add_argument("--can-option", action="append", default=[], metavar="KEY=VALUE",
                        help="a keyword argument of the python-can interface, e.g. fd=true (repeatable)")
    parser.add_argument("--can-config", default=None, metavar="SECTION",
                        help="section of python-can's configuration file (~/.canrc) to read, default [default]")


def bus_from_args(args: argparse.Namespace) -> BusConfig:
    return BusConfig(args.interface, args.channel, args.bitrate, parse_options(args.can_option), args.can_config)


# ---------------------------------------------------------------------- ecu
def add_ecu_arguments(parser: argparse.ArgumentParser) -> None:
    add_bus_arguments(parser, "slcan-pty: open a pty and act as an SLCAN adapter (prints SLCAN_PTY <path>)",
                      "slcan-pty")
    parser.add_argument("--clock", choices=[m.value for m in ClockMode], default=ClockMode.LOCKSTEP.value)
    parser.add_argument("--profile", default=DEFAULT_PROFILE, help="chassis profile: shipped name or folder")
    parser.add_argument("--truth", action=argparse.BooleanOptionalAction, default=None,
                        help="publish the plant's true pose for measuring (default: the profile's setting)")
    parser.add_argument("--plant", default="kinematic", help="'kinematic', 'pybullet' or 'package.module:factory'")
    parser.add_argument("--plant-arg", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--scenario", help="use the PyBullet car of this scenario (name or .toml) as the plant")
    parser.add_argument("--max-steer-deg", type=positive, default=math.degrees(EcuLimits.max_steer))
    parser.add_argument("--max-steer-rate-deg", type=positive, default=math.degrees(EcuLimits.max_steer_rate))
    parser.add_argument("--estop-decel", type=positive, default=EcuLimits.estop_decel)
    parser.add_argument(
        "--duration", type=seconds, default=None, help="wall seconds to run (default: until SIGTERM)"
    )


def ecu_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="ld3 ecu", description="Run the chassis ECU emulator on a CAN bus.")
    add_ecu_arguments(parser)
    return parser


def _plant(args: argparse.Namespace, plant_factory: PlantFactory | None) -> ChassisPort:
    try:
        kwargs = dict(item.split("=", 1) for item in args.plant_arg)
    except ValueError:
        raise UserError(f"--plant-arg takes KEY=VALUE, got {args.plant_arg}") from None
    for key, value in kwargs.items():
        try:
            number = float(value)
        except ValueError:
            continue
        if not math.isfinite(number) or (key in POSITIVE_PLANT_ARGS and number <= 0):
            raise UserError(f"--plant-arg {key}={value}: must be a finite number"
                            + (" > 0" if key in POSITIVE_PLANT_ARGS else ""))
    if args.scenario:
        from hil.emulator.plants import plant_args_for, pybullet_plant
        from testbed.eval.run.scenario import load_scenario

        return pybullet_plant(**{**plant_args_for(load_scenario(args.scenario)), **kwargs})
    factory = plant_factory or resolve_plant(args.plant)
    try:
        inspect.signature(factory).bind(**kwargs)
    except TypeError as exc:
        takes = ", ".join(inspect.signature(factory).parameters)
        raise UserError(f"--plant {args.plant}: {exc} (its --plant-arg keys: {takes})") from None
    return factory(**kwargs)


def run_ecu(args: argparse.Namespace, plant_factory: PlantFactory | None = None) -> int:
    """Run the ECU emulator until SIGTERM/SIGINT or --duration; slcan-pty prints `SLCAN_PTY <path>` first."""
    profile = load_profile(args.profile)
    key = link_key(profile, args.interface, args.channel)
    plant = _plant(args, plant_factory)
    limits = EcuLimits(
        max_steer=math.radians(args.max_steer_deg),
        max_steer_rate=math.radians(args.max_steer_rate_deg),
        estop_decel=args.estop_decel,
    )
    try:
        bus: can.BusABC = SlcanPtyBus() if args.interface == "slcan-pty" else bus_from_args(args).open()
    except LINK_ERRORS as exc:
        print(link_error_line(exc), file=sys.stderr)
        return EXIT_LINK
    done = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: done.set())
    ecu = EcuEmulator(bus, plant, limits, ClockMode(args.clock), profile=profile, truth=args.truth, key=key)
    ecu.start()
    if isinstance(bus, SlcanPtyBus):
        print(f"{READY_PREFIX}{bus.tty_path}", flush=True)
    done.wait(args.duration)
    ecu.stop()
    bus.shutdown()
    return 0


def ecu_main(argv: Sequence[str] | None = None, plant_factory: PlantFactory | None = None) -> int:
    return run_ecu(ecu_parser().parse_args(argv), plant_factory)


# ---------------------------------------------------------------------- replay
def parse_ids(text: str | None, default: frozenset[int]) -> frozenset[int] | None:
    """`--ids`: None -> `default`; "all" -> None (every frame); else comma-separated IDs (0x130 or 304)."""
    if text is None:
        return default
    if text == "all":
        return None
    try:
        return frozenset(int(part, 0) for part in text.split(","))
    except ValueError:
        raise UserError(f"--ids takes 'all' or comma-separated frame IDs such as 0x130,0x131, got {text!r}") from None


def replay_main(log_path: Path, bus_config: BusConfig, *, ids: str | None = None, yes: bool = False,
                profile: str = DEFAULT_PROFILE) -> int:
    """Play the command frames (or `ids`) of a .asc/.blf log onto the bus, paced by the log's timestamps; a
    hardware bus needs `yes`."""
    if not log_path.is_file():
        raise FileNotFoundError(f"CAN log not found: {log_path}")
    chosen = parse_ids(ids, load_profile(profile).command_ids)
    where = f"{bus_config.interface}:{bus_config.kwargs().get('channel') or 'default'}"
    if not yes and bus_config.hardware:
        raise UserError(f"refusing to replay onto {where} (a hardware bus can move a vehicle); add --yes to confirm")
    try:
        bus = bus_config.open()
    except LINK_ERRORS as exc:
        print(link_error_line(exc), file=sys.stderr)
        return EXIT_LINK
    try:
        count = replay_log(log_path, bus, ids=chosen)
    finally:
        bus.shutdown()
    which = "all" if chosen is None else ",".join(f"0x{i:03X}" for i in sorted(chosen))
    print(f"replayed {count} frames (IDs {which}) from {log_path} onto {where}")
    return 0


# ---------------------------------------------------------------------- hil
BASIS_WORDS = {"plant": "the emulated plant's pose", "odometry": "the bridge's odometry"}


def result_line(summary: Mapping[str, Any]) -> str:
    """The consequence and max |D| of a run over CAN, naming the pose they are judged on, and odometry's own max
    |D| beside them where that is another pose."""
    def metres(value: float | None) -> str:
        return "n/a" if value is None else f"{value:.3f} m"

    line = (f"on {BASIS_WORDS[summary['consequence_basis']]}: consequence {summary['consequence']}, "
            f"max |D| {metres(summary['max_abs_dev_m'])}")
    if summary["consequence_basis"] != "odometry":
        line += f" (odometry's max |D| {metres(summary['odometry_max_abs_dev_m'])})"
    return line


def cmd_hil(args: argparse.Namespace) -> int:
    """`ld3 hil SCENARIO ...` runs the scenario over CAN; `ld3 hil replay LOG ...` replays a log."""
    if args.scenario == REPLAY:
        if args.log is None:
            raise UserError("hil replay needs the log file: ld3 hil replay LOG.asc")
        return replay_main(args.log, bus_from_args(args), ids=args.ids, yes=args.yes, profile=args.profile)
    if args.log is not None:
        raise UserError(f"unexpected argument {str(args.log)!r} after the scenario")
    # before importing the run: its world is the simulator's, and a missing extra must name itself
    require_modules(("pybullet", "cv2"), "sim", "ld3 hil (its world is the simulator's)")
    from hil.emulator.scenario_run import LinkConfig, run_hil_scenario
    from testbed.cli import scenario_from_args

    sc = scenario_from_args(args)
    load_profile(args.profile)
    out = args.out or Path("runs") / f"{sc.name}-{sc.seed}-hil"
    check_out_dir(out, args.force)
    config = LinkConfig(args.interface, args.channel, ClockMode(args.clock) if args.clock else None,
                        args.profile, args.truth, args.bitrate, parse_options(args.can_option), args.can_config)
    drill: dict[str, object] = {}
    if args.drill:
        from hil.emulator.fault_drill import DRILL_REPLY_TIMEOUT_S, drill_installer, parse_drill

        if args.interface != "virtual":
            raise UserError("--drill needs the in-process ECU emulator (--interface virtual)")
        kind, at = parse_drill(args.drill)
        if at >= sc.duration:
            raise UserError(f"--drill {args.drill}: at {at:g} s it would never fire in a {sc.duration:g} s run; "
                            f"choose a time before the end")
        drill = {"prepare": drill_installer(kind, at), "reply_timeout": DRILL_REPLY_TIMEOUT_S}
    try:
        result = run_hil_scenario(sc, out, config, log_path=args.can_log, progress=sys.stderr.isatty(),
                                  record=args.record, sensors=args.sensors, force=args.force, **drill)
    except LINK_ERRORS as exc:
        print(link_error_line(exc), file=sys.stderr)
        return EXIT_LINK
    s = result.summary
    print(f"{sc.name} over {s['interface']} ({s['clock']}): {result_line(s)}, detected {s['detected']}, "
          f"{s['sim_time_s']:.1f} s simulated at {s['real_time_factor']:.1f}x real time")
    print(f"CAN: {s['can_frames_tx']} frames sent, {s['can_frames_rx']} received, "
          f"{s['can_frames_rejected']} rejected; log {out / s['can_log']}")
    print(f"outputs: {out}/summary.json, trajectory.csv, birdseye.png" + (", run.mcap" if args.record else ""))
    faults = chassis_faults(s)
    if faults:
        first = faults[0]
        stop = f"standstill at {s['stop_time_s']:.2f} s" if s["stop_time_s"] is not None else "no standstill"
        print(f"ld3: chassis fault: {first['kind']} at {first['time']:.2f} s ({first['detail']}); {stop}; "
              f"outputs in {out}", file=sys.stderr)
        return EXIT_CHASSIS_FAULT
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add `ld3 hil`, `ld3 ecu`, `ld3 vehicle`, `ld3 replay`, `ld3 ld detect` and `ld3 ld eval --labels` to the ld3
    command (entry points "ld3.commands")."""
    from testbed.cli import _add_run_overrides

    p = sub.add_parser("hil", help="run a scenario over CAN (or `ld3 hil replay LOG`: play a CAN log onto a bus)",
                       description="Run SCENARIO with the CAN bridge as the chassis (outputs as `ld3 run`, plus "
                                   "the CAN log), or `ld3 hil replay LOG` to play a recorded log onto a bus.")
    _add_run_overrides(p)
    p.add_argument("log", nargs="?", type=Path, help="with `replay`: the .asc/.blf log to play")
    add_bus_arguments(p, "virtual: in-process ECU; slcan: ECU process on a pty (or the adapter at --channel); "
                         "any other: the chassis on that interface and --channel (hardware rules)")
    p.add_argument("--clock", choices=[m.value for m in ClockMode], default=None,
                   help="lockstep (default on an emulator's bus) or realtime (default on hardware)")
    p.add_argument("--log", dest="can_log", type=Path, default=None,
                   help="CAN log file (.asc or .blf; default OUT/can.asc)")
    p.add_argument("--record", action="store_true",
                   help="also write run.mcap (Foxglove): the run's channels plus the CAN frames decoded by the DBC")
    p.add_argument("--profile", default=DEFAULT_PROFILE,
                   help="chassis profile: a shipped name (ld3-dev, ld3-dev-secoc, pix-hooke) or a folder with "
                        "chassis.dbc and profile.toml")
    p.add_argument("--truth", action=argparse.BooleanOptionalAction, default=None,
                   help="an emulated chassis also publishes its true pose, for measuring odometry drift only")
    p.add_argument("--ids", default=None, help="with `replay`: frame IDs to send (default the profile's commands; "
                                                "'all' for every frame)")
    p.add_argument("--yes", action="store_true", help="with `replay`: allow a hardware bus")
    p.add_argument("--sensors", choices=("sim", "io"), default="sim",
                   help="io: the simulated GNSS goes out as NMEA on a pty and comes back through the NMEA reader, "
                        "the camera frames through the camera reader (needs --localization msf)")
    p.add_argument("--drill", default=None, metavar="KIND[@T]",
                   help="inject a fault into the emulated chassis at T s (see hil.emulator.fault_drill), "
                        "e.g. chassis_estop@2")
    p.set_defaults(func=cmd_hil)

    p = sub.add_parser("ecu", help="run the chassis ECU emulator on a CAN bus", description=ecu_parser().description)
    add_ecu_arguments(p)
    p.set_defaults(func=run_ecu)

    add_vehicle_parser(sub, add_bus_arguments, bus_from_args)
    add_replay_parser(sub)
    add_detect_parser(sub.choices["ld"])
    add_labels_arguments(sub.choices["ld"])


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["ecu"]:
            return ecu_main(argv[1:])
        if argv[:1] == [REPLAY]:
            parser = OneLineParser(prog="python -m hil replay", description="Play a CAN log onto a bus.")
            parser.add_argument("log", type=Path)
            add_bus_arguments(parser, "the bus to play onto")
            parser.add_argument("--ids", default=None)
            parser.add_argument("--yes", action="store_true")
            parser.add_argument("--profile", default=DEFAULT_PROFILE)
            args = parser.parse_args(argv[1:])
            return replay_main(args.log, bus_from_args(args), ids=args.ids, yes=args.yes, profile=args.profile)
    except (ValueError, FileNotFoundError) as exc:
        print(f"ld3: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print("usage: python -m hil ecu|replay ...", file=sys.stderr)
    return EXIT_USAGE
