"""The ECU emulator as its own process speaking SLCAN on a pty: start it, learn its tty path, stop it.

The child runs `python -m hil ecu --interface slcan-pty ...` and prints one line `SLCAN_PTY <path>` once its
pty is open; the parent then opens python-can's slcan interface on that path.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Mapping

from hil.link.timing import ClockMode

READY_PREFIX = "SLCAN_PTY "


class EcuProcessError(RuntimeError):
    """The ECU process did not come up."""


class EcuProcess:
    """A running ECU emulator subprocess on a fresh pty (`tty_path`)."""

    def __init__(
        self,
        plant: str = "kinematic",
        plant_args: Mapping[str, str] | None = None,
        clock: ClockMode = ClockMode.LOCKSTEP,
        profile: str = "ld3-dev",
        truth: bool | None = None,
    ) -> None:
        command = [sys.executable, "-m", "hil", "ecu", "--interface", "slcan-pty", "--clock", clock.value]
        command += ["--plant", plant, "--profile", str(profile)]
        if truth is not None:
            command += ["--truth" if truth else "--no-truth"]
        for key, value in (plant_args or {}).items():
            command += ["--plant-arg", f"{key}={value}"]
        # its own session: a Ctrl-C meant for the run reaches the bridge, which brakes and then stops the ECU
        self.popen = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, start_new_session=True)
        assert self.popen.stdout is not None
        line = self.popen.stdout.readline()
        if not line.startswith(READY_PREFIX):
            self.stop()
            code = self.popen.returncode
            raise EcuProcessError(f"ECU process did not start: first line {line!r}, exit {code}")
        self.tty_path = line[len(READY_PREFIX) :].strip()

    def stop(self, timeout: float = 5.0) -> int | None:
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(timeout)
        if self.popen.stdout is not None:
            self.popen.stdout.close()
        return self.popen.returncode
