"""Which python-can bus the CAN link uses: any interface python-can knows (`can.interfaces.VALID_INTERFACES`,
entry points included), with channel, bitrate and options from the command line, filled in from python-can's
own configuration (`can.util.load_config`: `CAN_*` environment variables, `~/.canrc`, a `context` section)
where that names the same interface. The virtual bus and SLCAN on a pseudo-terminal are emulators; every
other bus is hardware."""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import can
import can.util

from hil.link.faults import one_line
from testbed.errors import UserError

DEFAULT_VIRTUAL_CHANNEL = "ld3-chassis"
DEFAULT_BITRATE = 500_000
NEEDS_CHANNEL = {
    "socketcan": "the CAN network interface, e.g. can0",
    "slcan": "the serial device or pty path of the adapter",
    "serial": "the serial device of the adapter",
}
"""Interfaces python-can cannot open without a channel, and what the channel names."""
NO_BITRATE = frozenset({"virtual", "socketcan", "socketcand", "udp_multicast"})
"""Interfaces whose bitrate is set outside python-can (or that have none): no default bitrate is passed."""


def interfaces() -> tuple[str, ...]:
    """Every interface name python-can accepts here, sorted."""
    return tuple(sorted(can.interfaces.VALID_INTERFACES))


def is_simulated_bus(interface: str, channel: str | None) -> bool:
    """True for the virtual bus and for SLCAN on a pseudo-terminal (an emulator), False for hardware."""
    if interface in ("virtual", "slcan-pty"):
        return True
    return interface == "slcan" and channel is not None and os.path.realpath(channel).startswith("/dev/pts/")


def parse_options(items: list[str] | tuple[str, ...]) -> dict[str, Any]:
    """`KEY=VALUE` strings -> bus keyword arguments, values typed as python-can types its config files."""
    options: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UserError(f"--can-option takes KEY=VALUE (a keyword of the python-can interface), got {item!r}")
        options[key.strip()] = can.util.cast_from_string(value.strip())
    return options


class BusOpenError(can.CanInitializationError):
    """The interface's driver is missing or its device could not be opened; the message is one line."""


def _configured(interface: str, context: str | None) -> dict[str, Any]:
    """python-can's own configuration, where it names `interface` (else nothing)."""
    try:
        config = dict(can.util.load_config(context=context))
    except can.CanInterfaceNotImplementedError:
        return {}
    return config if config.get("interface") == interface else {}


class _DriverNotes(logging.Handler):
    """What python-can's drivers log (warnings and worse) by logger name: a driver whose library is absent says
    so once, when it is first imported; a later failure to open it is explained by that note."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.notes: dict[str, list[str]] = {}

    def emit(self, record: logging.LogRecord) -> None:
        self.notes.setdefault(record.name, []).append(" ".join(record.getMessage().split()))

    def about(self, interface: str) -> list[str]:
        return [note for name, notes in self.notes.items() if interface in name.split(".") for note in notes]


_DRIVER_NOTES = _DriverNotes()
logging.getLogger("can").addHandler(_DRIVER_NOTES)  # also keeps them off the console where nothing else logs


@dataclass(frozen=True)
class BusConfig:
    """A bus selection: `interface` any python-can interface name, `channel` its channel (virtual name, serial
    path, netdev, adapter index), `bitrate` and interface `options`; `context` a section of python-can's
    configuration file to fill in what the command line leaves out."""

    interface: str = "virtual"
    channel: str | int | None = None
    bitrate: int | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    context: str | None = None

    def __post_init__(self) -> None:
        if self.interface not in can.interfaces.VALID_INTERFACES:
            raise UserError(f"unknown CAN interface {self.interface!r}; python-can knows {', '.join(interfaces())}")

    @property
    def hardware(self) -> bool:
        """Everything but the virtual bus and SLCAN on a pty gets the hardware rules."""
        channel = self.kwargs().get("channel")
        return not is_simulated_bus(self.interface, None if channel is None else str(channel))

    def kwargs(self) -> dict[str, Any]:
        """The keyword arguments of `can.Bus`: the command line's values over python-can's configuration."""
        if self.interface == "virtual":
            return {"interface": "virtual", "channel": self.channel or DEFAULT_VIRTUAL_CHANNEL}
        channel = can.util.cast_from_string(self.channel) if isinstance(self.channel, str) else self.channel
        given = {"interface": self.interface, "channel": channel, "bitrate": self.bitrate, **self.options}
        merged = {**_configured(self.interface, self.context),
                  **{key: value for key, value in given.items() if value is not None}}
        if merged.get("channel") is None and self.interface in NEEDS_CHANNEL:
            raise UserError(f"{self.interface} needs --channel: {NEEDS_CHANNEL[self.interface]}")
        if "bitrate" not in merged and self.interface not in NO_BITRATE:
            merged["bitrate"] = DEFAULT_BITRATE
        if self.interface == "slcan":
            merged.setdefault("sleep_after_open", 0)
        return merged

    def open(self) -> can.BusABC:
        """The open bus; a missing driver or an absent device raises BusOpenError naming the interface."""
        kwargs = self.kwargs()
        try:
            return can.Bus(**kwargs)
        except Exception as exc:  # a driver's own failure, whatever its type, is a failure to open the link
            raise BusOpenError(self._failure(kwargs.get("channel"), exc, _DRIVER_NOTES.about(self.interface))) from None

    def _failure(self, channel: object, exc: Exception, notes: list[str]) -> str:
        where = f"interface {self.interface}" + (f" channel {channel}" if channel is not None else "")
        if notes and isinstance(exc, NameError | AttributeError | TypeError):
            # a driver whose library failed to load logs why, then fails in some unrelated way
            reason, missing = "; ".join(notes), True
        else:
            reason = one_line(exc)
            missing = isinstance(exc, can.CanInterfaceNotImplementedError | ImportError) or "librar" in reason.lower()
        return f"{where}: {'driver missing' if missing else 'cannot open the device'}: {reason}"
