"""Benchmarks of the CAN link on the virtual bus with an in-process lockstep ECU and the kinematic plant:
command -> report round trip (median, p99) and a long soak counting lost frames."""

from __future__ import annotations

import statistics
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager

import can

from hil.emulator.ecu import EcuEmulator
from hil.emulator.kinematic_plant import KinematicBicyclePlant
from hil.link.bridge import CanChassisBridge
from testbed.chassis import ChassisCommand


@contextmanager
def virtual_link() -> Iterator[tuple[CanChassisBridge, EcuEmulator]]:
    """An engaged bridge and its ECU on a fresh virtual channel."""
    channel = f"ld3-bench-{uuid.uuid4().hex}"
    ecu_bus = can.Bus(interface="virtual", channel=channel)
    bridge_bus = can.Bus(interface="virtual", channel=channel)
    ecu = EcuEmulator(ecu_bus, KinematicBicyclePlant())
    ecu.start()
    bridge = CanChassisBridge(bridge_bus)
    try:
        bridge.engage()
        yield bridge, ecu
    finally:
        bridge.close()
        ecu.stop()
        bridge_bus.shutdown()
        ecu_bus.shutdown()


def round_trip_benchmark(n: int = 2000) -> dict[str, float]:
    """Wall time of n 20 ms lockstep cycles: command frames + step request out, full report set back."""
    samples = []
    with virtual_link() as (bridge, _):
        for k in range(n):
            bridge.send(ChassisCommand(0.01 * ((k % 20) - 10) / 10, 0.5 if k % 50 < 25 else -0.5))
            start = time.perf_counter()
            bridge.advance(0.02)
            samples.append((time.perf_counter() - start) * 1e6)
    samples.sort()
    return {
        "n": n,
        "median_us": statistics.median(samples),
        "p99_us": samples[min(len(samples) - 1, int(0.99 * len(samples)))],
    }


def soak(sim_seconds: float = 600.0) -> dict[str, float]:
    """sim_seconds of 50 Hz cycles; frames sent by each side against frames verified by the other."""
    steps = round(sim_seconds / 0.02)
    start = time.perf_counter()
    with virtual_link() as (bridge, ecu):
        tx0, rx0, ecu_rx0, ecu_tx0 = bridge.frames_tx, bridge.frames_rx, ecu.frames_rx, ecu.frames_tx
        for k in range(steps):
            bridge.send(ChassisCommand(0.0, 0.2 if (k // 500) % 2 == 0 else -0.2))
            bridge.advance(0.02)
        sent = (bridge.frames_tx - tx0) + (ecu.frames_tx - ecu_tx0)
        received = (ecu.frames_rx - ecu_rx0) + (bridge.frames_rx - rx0)
        rejected = sum(bridge.rejected.values()) + sum(ecu.guard.rejected.values())
        faults = bridge.read().faults
    return {
        "sim_seconds": sim_seconds,
        "steps": steps,
        "frames_sent": sent,
        "frames_received": received,
        "lost": sent - received,
        "rejected": rejected,
        "faults": len(faults),
        "wall_s": time.perf_counter() - start,
    }
