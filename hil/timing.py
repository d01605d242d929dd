"""Clock modes of the CAN link and the command-cycle rule shared by the bridge and the ECU emulator.

lockstep (simulation): plant time advances only when the bridge sends SIM_StepRequest(dt); the ECU
applies the commands received so far, steps its plant by dt and answers with one report set closed by
SIM_StepDone. Runs are deterministic and time-outs are measured in plant time. realtime (hardware): both
sides pace themselves on the wall clock at 50 Hz; time-outs are wall time.

Reports (both modes): each report message goes out at its own period (the DBC's cycle time, a multiple of
the command cycle): at the first step whose end has reached its next due time, which then moves to the next
multiple of the period; in realtime a step up to half a cycle early counts as on time (wall-clock jitter).

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


class ReportSchedule:
    """Per-message publication at its period: `due(name, t_us)` is True once per period boundary reached
    (`early_us` before the boundary counts as reached)."""

    def __init__(self, periods_us: dict[str, int], early_us: int = 0) -> None:
        self._periods = dict(periods_us)
        self._early = early_us
        self._next_us = dict.fromkeys(self._periods, 0)

    def due(self, name: str, t_us: int) -> bool:
        t = t_us + self._early
        if t < self._next_us[name]:
            return False
        period = self._periods[name]
        self._next_us[name] = (t // period + 1) * period
        return True
