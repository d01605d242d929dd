"""Where a secured profile's key comes from: the environment variable its [secoc] table names (the chassis
key, 32 hex digits), or else its published test key, which only an emulator's bus may use (the virtual bus,
SLCAN on a pty): a test key never goes onto a real bus by default."""

from __future__ import annotations

import os

from hil.link.bus_config import is_simulated_bus
from hil.link.profile import ChassisProfile
from hil.link.secoc import key_from_hex
from testbed.errors import UserError


class SecocKeyError(UserError):
    """No usable key for a secured profile on this bus; the message names the fix."""


def link_key(profile: ChassisProfile, interface: str, channel: str | None) -> bytes | None:
    """The key for a link on `interface`/`channel`; None where the profile authenticates nothing."""
    spec = profile.secoc
    if spec is None:
        return None
    text = os.environ.get(spec.key_env)
    if text:
        try:
            return key_from_hex(text.strip())
        except ValueError as exc:
            raise SecocKeyError(f"{spec.key_env}: {exc}") from None
    fix = f"set {spec.key_env} to the chassis's 128-bit key (32 hex digits)"
    if spec.test_key is None:
        raise SecocKeyError(f"profile {profile.name} authenticates frames and has no key: {fix}")
    if not is_simulated_bus(interface, channel):
        raise SecocKeyError(f"profile {profile.name}: refusing its published test key on {interface}:{channel} "
                            f"(not an emulator's bus): {fix}")
    return spec.test_key
