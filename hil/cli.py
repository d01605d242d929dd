"""Command-line entry points of the CAN link: `ecu` (run the ECU emulator), `replay` (play a log onto a bus).

`main(argv)` dispatches `python -m hil ecu|replay ...`; the `ld3` command can call `ecu_main` / `replay_main`.
A plant is named by `--plant`: "kinematic" (hil.kinematic_plant) or "package.module:factory", called with the
`--plant-arg KEY=VALUE` pairs as keyword strings and returning a ChassisPort.
"""

from __future__ import annotations

import argparse
import importlib
import math
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path

import can

from hil.bus_config import INTERFACES, BusConfig
from hil.ecu import EcuEmulator, EcuLimits
from hil.ecu_process import READY_PREFIX
from hil.kinematic_plant import KinematicBicyclePlant
from hil.replay import replay_log
from hil.slcan_pty import SlcanPtyBus
from hil.timing import ClockMode
from testbed.chassis import ChassisPort

PlantFactory = Callable[..., ChassisPort]


def resolve_plant(spec: str) -> PlantFactory:
    """"kinematic" or "package.module:callable" -> a factory of ChassisPort."""
    if spec == "kinematic":
        return KinematicBicyclePlant
    module_name, _, attribute = spec.partition(":")
    if not attribute:
        raise ValueError(f"plant must be 'kinematic' or 'package.module:factory', got {spec!r}")
    return getattr(importlib.import_module(module_name), attribute)


def ecu_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ld3 ecu", description="Run the chassis ECU emulator on a CAN bus.")
    parser.add_argument("--interface", choices=(*INTERFACES, "slcan-pty"), default="virtual")
    parser.add_argument("--channel", default=None, help="virtual channel name, serial path or netdev")
    parser.add_argument("--clock", choices=[m.value for m in ClockMode], default=ClockMode.LOCKSTEP.value)
    parser.add_argument("--plant", default="kinematic", help="'kinematic' or 'package.module:factory'")
    parser.add_argument("--plant-arg", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--max-steer-deg", type=float, default=math.degrees(EcuLimits.max_steer))
    parser.add_argument("--max-steer-rate-deg", type=float, default=math.degrees(EcuLimits.max_steer_rate))
    parser.add_argument("--estop-decel", type=float, default=EcuLimits.estop_decel)
    parser.add_argument(
        "--duration", type=float, default=None, help="wall seconds to run (default: until SIGTERM)"
    )
    return parser


def ecu_main(argv: Sequence[str] | None = None, plant_factory: PlantFactory | None = None) -> int:
    """Run the ECU emulator until SIGTERM/SIGINT or --duration; slcan-pty prints `SLCAN_PTY <path>` first."""
    args = ecu_parser().parse_args(argv)
    plant_kwargs = dict(item.split("=", 1) for item in args.plant_arg)
    plant = (plant_factory or resolve_plant(args.plant))(**plant_kwargs)
    limits = EcuLimits(
        max_steer=math.radians(args.max_steer_deg),
        max_steer_rate=math.radians(args.max_steer_rate_deg),
        estop_decel=args.estop_decel,
    )
    if args.interface == "slcan-pty":
        bus: can.BusABC = SlcanPtyBus()
    else:
        bus = BusConfig(args.interface, args.channel).open()
    done = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: done.set())
    ecu = EcuEmulator(bus, plant, limits, ClockMode(args.clock))
    ecu.start()
    if isinstance(bus, SlcanPtyBus):
        print(f"{READY_PREFIX}{bus.tty_path}", flush=True)
    done.wait(args.duration)
    ecu.stop()
    bus.shutdown()
    return 0


def replay_main(log_path: Path, interface: str = "virtual", channel: str | None = None) -> int:
    """Play the frames of a .asc/.blf log onto the configured bus with their recorded timing."""
    bus = BusConfig(interface, channel).open()
    try:
        count = replay_log(log_path, bus)
    finally:
        bus.shutdown()
    print(f"replayed {count} frames from {log_path} onto {interface}:{channel or 'default'}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["ecu"]:
        return ecu_main(argv[1:])
    if argv[:1] == ["replay"]:
        parser = argparse.ArgumentParser(prog="ld3 hil replay", description="Play a CAN log onto a bus.")
        parser.add_argument("log", type=Path)
        parser.add_argument("--interface", choices=INTERFACES, default="virtual")
        parser.add_argument("--channel", default=None)
        args = parser.parse_args(argv[1:])
        return replay_main(args.log, args.interface, args.channel)
    print("usage: python -m hil ecu|replay ...", file=sys.stderr)
    return 2
