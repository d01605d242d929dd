"""Clock modes of the CAN link and the command-cycle rule shared by the bridge and the ECU emulator.

lockstep (simulation): plant time advances only when the bridge sends SIM_StepRequest(dt); the ECU
applies the commands received so far, steps its plant by dt and answers with one report set closed by
SIM_StepDone. Runs are deterministic and time-outs are measured in plant time. realtime (hardware): both
sides pace themselves on the wall clock at 50 Hz; time-outs are wall time.

Reports (both modes): each report message goes out at its own period (the DBC's cycle time rounded up to whole
command cycles): at the first step whose end has reached its next due time, which then moves to the next
multiple of the period; in realtime a step up to half a cycle early counts as on time (wall-clock jitter).

Command rule (both modes): a command cycle goes out at every multiple of the profile's cycle (20 ms), carrying
the loop's latest command while it is younger than one control period (in realtime, one control period and one
cycle: a tick a little late must not cost a cycle); a loop that stalls longer stops the cycles, and the
chassis's own command time-out trips. With 10 ms ticks the commands of ticks 0, 2, 4, ... go
out; with 25 ms ticks (40 Hz) the command of tick 0 goes out at 0 and 20 ms, that of tick 1 at 40 ms, and so on.
"""

from __future__ import annotations

from enum import Enum

from testbed.chassis import ChassisCommand

CYCLE_US = 20_000


class ClockMode(Enum):
    """How time advances on the link: see the module docstring."""

    LOCKSTEP = "lockstep"
    REALTIME = "realtime"


class CommandCycle:
    """The command rule: `at(t_us)`, for a cycle boundary t_us, is the command that cycle carries (None: none);
    a command stands for one control period (`loop_us`) plus `grace_us` of lateness of the next."""

    def __init__(self, period_us: int = CYCLE_US, grace_us: int = 0) -> None:
        self.period_us = period_us
        self.loop_us = period_us
        self.grace_us = grace_us
        self._command: ChassisCommand | None = None
        self._given_us = 0

    def give(self, command: ChassisCommand, t_us: int) -> None:
        """The loop's command of chassis time `t_us`."""
        self._command, self._given_us = command, t_us

    def at(self, t_us: int) -> ChassisCommand | None:
        if self._command is None or t_us - self._given_us >= self.loop_us + self.grace_us:
            return None
        return self._command

    def is_boundary(self, t_us: int) -> bool:
        return t_us % self.period_us == 0


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
