"""Composed attacks: a list of attacks run as one, each hook applied by every member in list order.

The chain's capabilities (its threat model) are the union of its members'; its state reports each member's
stage joined by `+` and the sum of their lateral offsets, and `describe()` lists every member's spec.
"""

from __future__ import annotations

from typing import Any

from testbed.attacks.base import Attack, AttackerView, WhiteBox
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.lane_detection import LaneDetection
from testbed.localization.estimate import LocalizationEstimate
from testbed.localization.sensors import GnssFix


class AttackChain(Attack):
    """Several attacks at once: GNSS, MSF-output and LD-output hooks each run through the members in order."""

    name = "chain"

    def __init__(self, members: list[Attack]) -> None:
        if len(members) < 2:
            raise UserError(f"an attack chain needs at least two attacks, got {len(members)}")
        super().__init__(min(m.start_time for m in members))
        self.members = list(members)

    @property
    def threat_model(self) -> frozenset[ThreatCapability]:
        return frozenset().union(*(m.threat_model for m in self.members))

    def know(self, whitebox: WhiteBox) -> None:
        super().know(whitebox)
        for member in self.members:
            member.know(whitebox)

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        for member in self.members:
            fix = member.spoof_gnss(fix, view)
        return fix

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        for member in self.members:
            est = member.tamper_msf(est, view)
        return est

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        for member in self.members:
            ld = member.tamper_ld(ld, view)
        return ld

    def painters(self) -> list[Any]:
        return [p for member in self.members for p in member.painters()]

    def state(self) -> dict[str, Any]:
        states = [m.state() for m in self.members]
        switches = [s["switch_time"] for s in states if s.get("switch_time") is not None]
        return {"stage": "+".join(str(s["stage"]) for s in states), "switch_time": min(switches, default=None),
                "offset": sum(float(s["offset"]) for s in states), "members": states}

    def describe(self) -> list[dict[str, Any]]:  # type: ignore[override]
        return [m.describe() for m in self.members]


def threat_model_of(attack: Attack | None) -> frozenset[ThreatCapability]:
    """The capabilities a run's attack acts through; empty without an attack."""
    return frozenset() if attack is None else attack.threat_model
