"""Command gaps on the wire under CPU load: `ld3 vehicle` on pix-hooke (realtime) against the ECU emulator, over
the virtual bus (the in-process ECU of `tests.hil.vehicle.vehicle_truth.TruthBench`, GGA from the plant's true pose) or
SLCAN on a pty (an ECU process; GGA at the start with σ 5 m, so the slow drive stays inside the MSF's gate),
with `--hogs` busy Python processes at nice 0. Prints the run's outcome and the p50/p99/largest gap between
DriveCtrl (0x130) frames the bridge sent, read back from can.asc with python-can's LogReader.

The emulator stands for the chassis's own controller, which has its own CPU: with `--ecu-fifo` its threads (and
the GNSS feed's) run at SCHED_FIFO 20, so that what is measured is the run's timing, not the emulator's.
Run from the repository root: PYTHONPATH=. python docs/can/command_gaps.py virtual|slcan [--hogs 4] [--ecu-fifo]
[--duration 10] [--out runs/gaps] [more ld3 vehicle arguments, e.g. --rt-priority 0]
"""

from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing
import os
import subprocess
import threading
import time
from pathlib import Path

import can
import numpy as np

from hil.link.ecu_process import EcuProcess
from hil.link.timing import ClockMode
from hil.vehicle.geodetic import DEFAULT_ORIGIN, LocalTangentPlane
from hil.vehicle.nmea_out import gga_sentence
from testbed.cli import main as ld3
from testbed.localization.sensors import GnssFix
from tests.hil.vehicle.test_vehicle import NmeaFeeder
from tests.hil.vehicle.vehicle_truth import TruthBench

PROFILE = "pix-hooke"
DRIVE_CTRL = 0x130
AUTONOMOUS = 1
EMULATOR_PRIORITY = 20


def hog(stop: multiprocessing.synchronize.Event) -> None:
    while not stop.is_set():
        sum(range(100_000))


class StillFeeder(NmeaFeeder):
    """GGA at 10 Hz at s = 5 m of parking-lot's lane 0, σ 5 m (autonomous fix), stamped with the wall clock."""

    def _feed(self) -> None:
        pose = self.track.start_pose(0, 5.0)
        plane = LocalTangentPlane(*DEFAULT_ORIGIN)
        while not self._stop.is_set():
            fix = GnssFix(time.time(), np.array((pose.x, pose.y)), np.eye(2) * 25.0)
            os.write(self.master, gga_sentence(fix, plane, AUTONOMOUS))
            self._stop.wait(0.1)


def emulator_fifo(threads: list[threading.Thread]) -> None:
    for thread in threads:
        if thread.native_id is not None:
            os.sched_setscheduler(thread.native_id, os.SCHED_FIFO, os.sched_param(EMULATOR_PRIORITY))


def drive(mode: str, out: Path, duration: float, ecu_fifo: bool, extra: list[str]) -> int:
    common = ["--map", "parking-lot", "--profile", PROFILE, "--defense", "none", "--detector", "none",
              "--duration", str(duration), "--out", str(out), "--force"]
    if mode == "virtual":
        bench = TruthBench(PROFILE, "parking-lot", 5.0)
        if ecu_fifo:
            emulator_fifo([t for t in threading.enumerate() if t is not threading.main_thread()])
        try:
            return ld3(["vehicle", *common, "--gnss", f"nmea:{bench.path}", "--interface", "virtual", "--channel",
                        bench.channel, "--speed", "2", *extra])
        finally:
            bench.close()
    ecu = EcuProcess(plant="kinematic", clock=ClockMode.REALTIME, profile=PROFILE)
    feeder = StillFeeder()
    if ecu_fifo:
        subprocess.run(["chrt", "-a", "-f", "-p", str(EMULATOR_PRIORITY), str(ecu.popen.pid)], check=True)
        emulator_fifo([feeder._thread])
    try:
        return ld3(["vehicle", *common, "--gnss", f"nmea:{feeder.path}", "--interface", "slcan", "--channel",
                    ecu.tty_path, "--speed", "0.5", *extra])
    finally:
        feeder.close()
        ecu.stop()


def gaps_ms(can_log: Path) -> list[float]:
    with can.LogReader(str(can_log)) as reader:
        sent = [m.timestamp for m in reader if m.arbitration_id == DRIVE_CTRL and not m.is_rx]
    return sorted((b - a) * 1e3 for a, b in itertools.pairwise(sent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mode", choices=["virtual", "slcan"])
    parser.add_argument("--hogs", type=int, default=4)
    parser.add_argument("--ecu-fifo", action="store_true")
    parser.add_argument("--duration", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=Path("runs/gaps"))
    args, extra = parser.parse_known_args()  # the rest goes to ld3 vehicle
    stop = multiprocessing.Event()
    hogs = [multiprocessing.Process(target=hog, args=(stop,), daemon=True) for _ in range(args.hogs)]
    for process in hogs:
        process.start()
    try:
        code = drive(args.mode, args.out, args.duration, args.ecu_fifo, extra)
    finally:
        stop.set()
        for process in hogs:
            process.join()
    summary = json.loads((args.out / "summary.json").read_text())
    gaps = gaps_ms(args.out / "can.asc")
    print(json.dumps({
        "mode": args.mode, "exit": code, "consequence": summary["consequence"],
        "faults": [f["kind"] for f in summary["faults"]], "loop": summary["loop_scheduling"],
        "pacer": summary["command_pacer"], "cycles": len(gaps) + 1, "gap_p50_ms": round(gaps[len(gaps) // 2], 2),
        "gap_p99_ms": round(gaps[int(0.99 * len(gaps))], 2), "gap_max_ms": round(gaps[-1], 2),
        "gaps_over_2_cycles": sum(g > 40.0 for g in gaps), "load_1min": os.getloadavg()[0]}))


if __name__ == "__main__":
    main()
