"""Failures of the CAN link (python-can, the serial device, the VCU's handshake, the ECU process) and the one
line that reports one."""

from __future__ import annotations

import can

from hil.link.bridge import BridgeError
from hil.link.ecu_process import EcuProcessError
from hil.link.faults import one_line

LINK_ERRORS: tuple[type[BaseException], ...] = (can.CanError, OSError, BridgeError, EcuProcessError)


def link_error_line(exc: BaseException) -> str:
    """One line for a failure of the CAN link."""
    return f"ld3: CAN link error: {one_line(exc)}"
