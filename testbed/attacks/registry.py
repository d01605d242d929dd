"""The attack registry: built-in attacks and the `ld3.attacks` entry points.

An attack component's factory is `factory(params, rng, defense)`: its validated parameters (numbers, and
strings for `text_params`), the run's attack random stream, and what it may know of the defense (an
object with CUSUM `b` and `tau`). `needs` says what the run must provide for the attack to act at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from testbed.attacks.drp import DrpBend, DrpPatch, DrpTrace
from testbed.attacks.fusionripper import FusionRipper
from testbed.attacks.stealthy import CusumKnowledge, StealthyAttack
from testbed.attacks.trace import Trace, TraceInjection
from testbed.registry import Capability, Component, Registry


def _resolve_trace(ref: str) -> Trace:
    if ref.endswith(".csv") or "/" in ref or "\\" in ref:
        return Trace.load(Path(ref).expanduser())
    return Trace.named(ref)


def _stealthy(p: dict[str, Any], rng, defense: Any) -> StealthyAttack:
    """The stealthy attacker knows the defense's CUSUM b, tau (and LD noise); spec values override."""
    base = CusumKnowledge()
    knowledge = CusumKnowledge(
        b=p.pop("b", getattr(defense, "b", base.b)),
        tau=p.pop("tau", getattr(defense, "tau", base.tau)),
        ld_noise_std=p.pop("ld_std", getattr(defense, "ld_noise_std", base.ld_noise_std)),
    )
    return StealthyAttack(knowledge, **p)


ATTACKS: Registry[Component] = Registry("attack kind", Component, "ld3.attacks")
ATTACKS.add(Component(
    "fusionripper", lambda p, rng, defense: FusionRipper(**p, rng=rng),
    "FusionRipper: lateral GNSS spoofing, profiling then aggressive", needs=frozenset({Capability.GNSS}),
    params=("d", "f", "direction", "start", "trigger", "obs_std"), text_params=("direction",)))
ATTACKS.add(Component(
    "trace", lambda p, rng, defense: TraceInjection(_resolve_trace(p.pop("trace", "default")), **p),
    "a recorded lateral-deviation trace injected into the localization output",
    params=("trace", "start", "scale"), text_params=("trace",)))
ATTACKS.add(Component(
    "stealthy", _stealthy, "white-box MSF offset kept just under LD3's CUSUM threshold",
    params=("start", "margin", "direction", "b", "tau", "ld_std"), text_params=("direction",)))
ATTACKS.add(Component(
    "drp-trace", lambda p, rng, defense: DrpTrace(**p), "an LD deviation trace (dirty road patch, modelled)",
    needs=frozenset({Capability.LANE_DETECTOR}), params=("start", "shift", "ramp", "duration")))
ATTACKS.add(Component(
    "drp-bend", lambda p, rng, defense: DrpBend(**p), "an LD deviation trace that also rotates the detected lines",
    needs=frozenset({Capability.LANE_DETECTOR}), params=("start", "shift", "bend", "ramp", "duration")))
ATTACKS.add(Component(
    "drp-patch", lambda p, rng, defense: DrpPatch(**p), "a dark patch painted on the road the camera sees",
    needs=frozenset({Capability.CAMERA_IMAGE}), params=("at", "length", "width", "offset", "angle", "darkness"),
    required=("at",)))
