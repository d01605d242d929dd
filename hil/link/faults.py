"""Faults that end a run over CAN: what the bridge detected, when, and the latch that keeps them.

Kinds: report_timeout (lost feedback), chassis_estop, chassis_fault (a fault signal reported nonzero),
control_lost (the chassis left self-driving), foreign_sender (a frame on a command ID, or more report frames
than the chassis sends), bad_frames (a run of rejected report frames), bus_error (error frame or bus-off),
send_error (the bus refused a frame), ecu_lost (no lockstep reply), bad_command (a non-finite command),
link_lost (the bus device or its peer is gone), interrupted (the operator stopped the run).
"""

from __future__ import annotations

from testbed.chassis import ChassisFault


def one_line(exc: BaseException) -> str:
    """An exception's text on one line (its type's name where it has none), for a fault's detail."""
    return " ".join(str(exc).split()) or type(exc).__name__


class FaultLatch:
    """Keeps the first occurrence of each fault kind, in order of detection."""

    def __init__(self) -> None:
        self._faults: dict[str, ChassisFault] = {}

    def raise_fault(self, kind: str, t: float, detail: str) -> None:
        if kind not in self._faults:
            self._faults[kind] = ChassisFault(kind, t, detail)

    def __bool__(self) -> bool:
        return bool(self._faults)

    def __contains__(self, kind: str) -> bool:
        return kind in self._faults

    @property
    def faults(self) -> tuple[ChassisFault, ...]:
        return tuple(self._faults.values())
