"""Threat models: the capabilities an attack declares and a run's threat model (the set of them).

`gnss` spoofs GNSS fixes before the MSF fuses them; `msf-output` tampers with the MSF's pose; `ld-output`
tampers with the lane detector's output; `road-paint` paints the road the camera sees. LD3's own threat
model is {gnss} or {msf-output} (paper §3); the paper also claims resilience to an attacker of the lane detector
alone, the MSF benign ({ld-output} or {road-paint}, §6.2). An attacker of both sources together is outside both.
"""

from __future__ import annotations

from collections.abc import Iterable
from enum import StrEnum

from testbed.errors import UserError


class ThreatCapability(StrEnum):
    """One place an attacker may act."""

    GNSS = "gnss"
    MSF_OUTPUT = "msf-output"
    LD_OUTPUT = "ld-output"
    ROAD_PAINT = "road-paint"


LD3_THREAT_MODELS: tuple[frozenset[ThreatCapability], ...] = (
    frozenset({ThreatCapability.GNSS}), frozenset({ThreatCapability.MSF_OUTPUT}),
    frozenset({ThreatCapability.LD_OUTPUT}), frozenset({ThreatCapability.ROAD_PAINT}))
"""The threat models LD3 claims: the attacker controls the localization only (paper §3) or the lane detector
only (§6.2, the LD-side adaptive attack)."""


def parse_threat(text: str | Iterable[str]) -> frozenset[ThreatCapability]:
    """`gnss,ld-output` (or an iterable of names) -> the threat model; UserError naming the known ones."""
    names = [n.strip() for n in (text.split(",") if isinstance(text, str) else text)]
    known = ", ".join(c.value for c in ThreatCapability)
    if not names or not all(names):
        raise UserError(f"threat model {text!r} names no capability; use a comma list of: {known}")
    caps = []
    for name in names:
        try:
            caps.append(ThreatCapability(name))
        except ValueError:
            raise UserError(f"unknown threat capability {name!r}; known: {known}") from None
    return frozenset(caps)


def threat_label(caps: Iterable[ThreatCapability]) -> str:
    """The threat model as a stable comma list (`gnss,msf-output`), or `none`."""
    order = [c.value for c in ThreatCapability]
    names = sorted({ThreatCapability(c).value for c in caps}, key=order.index)
    return ",".join(names) or "none"


def within_ld3_threat_model(caps: Iterable[ThreatCapability]) -> bool:
    """True when an attacker with `caps` is one LD3 claims to defend against (it controls one source only)."""
    have = frozenset(caps)
    return not have or any(have <= model for model in LD3_THREAT_MODELS)


def reaches_lines(caps: Iterable[ThreatCapability]) -> bool:
    """True when an attacker with `caps` acts on the lane detector's output or the road it sees."""
    return bool(frozenset(caps) & {ThreatCapability.LD_OUTPUT, ThreatCapability.ROAD_PAINT})


def reaches_pose(caps: Iterable[ThreatCapability]) -> bool:
    """True when an attacker with `caps` moves the localization's pose (its GNSS fixes or the MSF's output)."""
    return bool(frozenset(caps) & {ThreatCapability.GNSS, ThreatCapability.MSF_OUTPUT})
