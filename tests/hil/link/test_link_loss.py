"""A dead link or an operator's interruption ends a run as chassis_fault with its outputs: the ECU process killed
under a lockstep bridge and under `ld3 hil` in realtime latches link_lost, SIGINT to `ld3 hil` latches
interrupted; either way the car brakes, every output is written, the exit code is 3 and no thread prints a
traceback."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import pytest

from hil.link.bridge import CanChassisBridge
from hil.link.bus_config import BusConfig
from hil.link.ecu_process import READY_PREFIX, EcuProcess
from hil.link.interruption import interruptible
from tests.hil.link.driving import run, start_odometry

OUTPUTS = {"summary.json", "trajectory.csv", "birdseye.png", "can.asc"}
LD3 = [sys.executable, "-m", "testbed.cli"]


def test_killed_ecu_process_latches_link_lost_without_a_thread_traceback(monkeypatch):
    thread_errors: list[BaseException] = []
    monkeypatch.setattr(threading, "excepthook", lambda args: thread_errors.append(args.exc_value))
    process = EcuProcess(plant="tests.hil.link.driving:start_plant")
    bus = BusConfig("slcan", process.tty_path).open()
    bridge = CanChassisBridge(bus, reply_timeout=5.0, odometry=start_odometry())
    try:
        bridge.engage(timeout=5.0)
        run(bridge, 150)
        moving = bridge.read().speed
        process.popen.kill()
        started = time.monotonic()
        run(bridge, 150)
        elapsed = time.monotonic() - started
        faults = {f.kind: f for f in bridge.latched_faults()}
    finally:
        bridge.close()
        with contextlib.suppress(can.CanError):  # the device is gone: closing it fails
            bus.shutdown()
        process.stop()
    assert moving > 1.0
    assert "link_lost" in faults and faults["link_lost"].t >= 1.5 and faults["link_lost"].detail
    assert elapsed < 3.0  # no lockstep step waits out the reply time-out once the link is known dead
    assert bridge.read().speed < moving
    assert thread_errors == []


def test_interruptible_calls_back_once_then_raises_and_restores_the_handlers():
    before = signal.getsignal(signal.SIGINT)
    seen: list[str] = []
    with pytest.raises(KeyboardInterrupt), interruptible(seen.append):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.01)
        assert seen == ["SIGTERM"]
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1.0)
    assert seen == ["SIGTERM"] and signal.getsignal(signal.SIGINT) is before


def _wait_for(path: Path, popen: subprocess.Popen, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert popen.poll() is None, popen.communicate()
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.1)


def _finished(popen: subprocess.Popen, out: Path) -> tuple[dict, str]:
    _, err = popen.communicate(timeout=120)
    assert "Traceback" not in err, err
    assert popen.returncode == 3, err
    assert {p.name for p in out.iterdir()} >= OUTPUTS
    return json.loads((out / "summary.json").read_text()), err


def _ld3_lines(err: str) -> list[str]:
    """What ld3 itself printed on stderr (pybullet prints its build time when imported)."""
    return [line for line in err.splitlines() if not line.startswith("pybullet build time")]


def _hil(out: Path, *args: str) -> subprocess.Popen:
    argv = [*LD3, "hil", "parking-lot", "--clock", "realtime", "--duration", "12", "--seed", "1", "--out", str(out)]
    return subprocess.Popen([*argv, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_ld3_hil_with_its_ecu_process_killed_ends_as_chassis_fault_with_every_output(tmp_path):
    ecu = subprocess.Popen([sys.executable, "-m", "hil", "ecu", "--interface", "slcan-pty", "--clock", "realtime"],
                           stdout=subprocess.PIPE, text=True)
    try:
        line = ecu.stdout.readline()
        assert line.startswith(READY_PREFIX)
        out = tmp_path / "run"
        hil = _hil(out, "--interface", "slcan", "--channel", line[len(READY_PREFIX):].strip())
        _wait_for(out / "can.asc", hil)
        time.sleep(3.0)
        ecu.kill()
        summary, err = _finished(hil, out)
    finally:
        ecu.kill()
        ecu.wait()
    kinds = [f["kind"] for f in summary["faults"]]
    assert summary["consequence"] == "chassis_fault" and "link_lost" in kinds
    assert len(_ld3_lines(err)) == 1 and _ld3_lines(err)[0].startswith("ld3: chassis fault:")
    assert summary["can_frames_logged"] > 0 and summary["sim_time_s"] < 12.0


def test_sigint_to_ld3_hil_brakes_in_lane_and_keeps_every_output(tmp_path):
    out = tmp_path / "run"
    hil = _hil(out)
    _wait_for(out / "can.asc", hil)
    time.sleep(3.0)
    hil.send_signal(signal.SIGINT)
    summary, err = _finished(hil, out)
    first = summary["faults"][0]
    assert summary["consequence"] == "chassis_fault" and first["kind"] == "interrupted" and first["time"] > 1.0
    assert len(_ld3_lines(err)) == 1 and _ld3_lines(err)[0].startswith("ld3: chassis fault: interrupted at")
    assert summary["stop_time_s"] is not None and abs(summary["final_dev_m"]) < 0.2
