"""Which python-can bus the CAN link uses: virtual (in-process, the default), slcan on a serial device or pty,
or socketcan on a named kernel interface (real hardware)."""

from __future__ import annotations

import os
from dataclasses import dataclass

import can

from testbed.errors import UserError

INTERFACES = ("virtual", "slcan", "socketcan")
DEFAULT_VIRTUAL_CHANNEL = "ld3-chassis"
DEFAULT_BITRATE = 500_000


def is_simulated_bus(interface: str, channel: str | None) -> bool:
    """True for the virtual bus and for SLCAN on a pseudo-terminal (an emulator), False for hardware."""
    if interface in ("virtual", "slcan-pty"):
        return True
    return interface == "slcan" and channel is not None and os.path.realpath(channel).startswith("/dev/pts/")


@dataclass(frozen=True)
class BusConfig:
    """A bus selection: `interface` one of INTERFACES, `channel` the virtual name, serial path or netdev."""

    interface: str = "virtual"
    channel: str | None = None
    bitrate: int = DEFAULT_BITRATE

    def open(self) -> can.BusABC:
        if self.interface == "virtual":
            return can.Bus(interface="virtual", channel=self.channel or DEFAULT_VIRTUAL_CHANNEL)
        if self.interface == "slcan":
            if not self.channel:
                raise UserError("slcan needs --channel: the serial device or pty path of the adapter")
            return can.Bus(interface="slcan", channel=self.channel, bitrate=self.bitrate, sleep_after_open=0)
        if self.interface == "socketcan":
            if not self.channel:
                raise UserError("socketcan needs --channel: the CAN network interface, e.g. can0")
            return can.Bus(interface="socketcan", channel=self.channel)
        raise UserError(f"unknown CAN interface {self.interface!r}; choose one of {', '.join(INTERFACES)}")
