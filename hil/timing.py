"""Clock modes of the CAN link and the command-cycle rule shared by the bridge and the ECU emulator.

lockstep (simulation): plant time advances only when the bridge sends SIM_StepRequest(dt); the ECU
applies the commands received so far, steps its plant by dt and answers with one report set closed by
SIM_StepDone. Runs are deterministic and time-outs are measured in plant time. realtime (hardware): both
sides pace themselves on the wall clock at 50 Hz; time-outs are wall time.

Command rule (both modes): a command cycle goes out at the start of a tick whose time t has reached the
next due time, if the loop gave a command since the last cycle; due times are the multiples of the profile's
cycle (20 ms), so with 10 ms ticks the commands of ticks 0, 2, 4, ... are sent and held for 20 ms, and the
commands given at odd ticks are never applied.
"""

from __future__ import annotations

from enum import Enum

CYCLE_US = 20_000


class ClockMode(Enum):
    """How time advances on the link: see the module docstring."""

    LOCKSTEP = "lockstep"
    REALTIME = "realtime"


class CommandSchedule:
    """The 50 Hz sample-and-hold rule: `due(t_us)` is True once per 20 ms boundary reached."""

    def __init__(self, period_us: int = CYCLE_US) -> None:
        self._period = period_us
        self._next_us = 0

    def due(self, t_us: int) -> bool:
        if t_us < self._next_us:
            return False
        self._next_us = (t_us // self._period + 1) * self._period
        return True
