"""The attack registry: built-in attacks and the `ld3.attacks` entry points.

An attack component's factory is `factory(params, rng, defense)`: the parameters the scenario gives,
validated by the component's `params` model (built from the attack's constructor), the run's attack
random stream, and what it may know of the defense (an object with CUSUM `b` and `tau`). `needs` says
what the run must provide for the attack to act at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field, create_model

from testbed.attacks.drp import DrpBend, DrpPatch, DrpTrace
from testbed.attacks.fusionripper import FusionRipper
from testbed.attacks.stealthy import CusumKnowledge, StealthyAttack
from testbed.attacks.trace import Trace, TraceInjection
from testbed.params import Params, params_from_signature
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


_DESCRIPTIONS = {
    "start": "time the attack starts (s)", "d": "spoofed lateral GNSS offset while profiling (m)",
    "f": "aggressive stage: the offset is multiplied by f every second", "direction": "left or right",
    "trigger": "victim's physical deviation that ends profiling (m)",
    "spread": "stealthy: time over which the initial τ burst is spent (s; 0 = one CUSUM tick, as the paper)",
    "obs_std": "noise of the attacker's view of the deviation (m)",
    "trace": "a shipped trace name or a CSV path", "scale": "factor on the trace's deviation",
    "margin": "safety margin under the CUSUM bound (m); default 3 × the LD noise",
    "b": "the CUSUM weight the attacker assumes (m); default: the defense's",
    "tau": "the CUSUM threshold the attacker assumes (m); default: the defense's",
    "ld_std": "the LD noise the attacker assumes (m)", "shift": "lateral shift of the detected lines (m, + left)",
    "ramp": "time to reach the full shift (s)", "duration": "how long the shift holds (s)",
    "bend": "rotation of the detected lines (rad)", "at": "arc length of the patch centre (m)",
    "length": "patch length along the road (m)", "width": "patch width (m)",
    "offset": "lateral offset of the patch centre from the reference line (m, + left)",
    "angle": "patch rotation (rad)", "darkness": "how much darker than the asphalt (0..1)",
}


def _params(name: str, cls: type, skip: tuple[str, ...] = (), **extra: Any) -> type[Params]:
    """The attack's parameter model: its constructor's keywords (less `skip`), plus `extra` fields."""
    base = params_from_signature(f"{name}-params", cls.__init__, skip, _DESCRIPTIONS)
    fields = {k: (typ, Field(default, description=_DESCRIPTIONS.get(k))) for k, (typ, default) in extra.items()}
    return create_model(f"{name}-params", __base__=base, **fields) if fields else base


ATTACKS: Registry[Component] = Registry("attack kind", Component, "ld3.attacks")
ATTACKS.add(Component(
    "fusionripper", lambda p, rng, defense: FusionRipper(**p, rng=rng),
    "FusionRipper: lateral GNSS spoofing, profiling then aggressive", needs=frozenset({Capability.GNSS}),
    params=_params("fusionripper", FusionRipper, ("rng",))))
ATTACKS.add(Component(
    "trace", lambda p, rng, defense: TraceInjection(_resolve_trace(p.pop("trace", "default")), **p),
    "a recorded lateral-deviation trace injected into the localization output",
    params=_params("trace", TraceInjection, ("trace",), trace=(str, "default"))))
ATTACKS.add(Component(
    "stealthy", _stealthy, "white-box MSF offset kept just under LD3's CUSUM threshold",
    params=_params("stealthy", StealthyAttack, ("knowledge",), b=(float | None, None), tau=(float | None, None),
                   ld_std=(float | None, None))))
ATTACKS.add(Component(
    "drp-trace", lambda p, rng, defense: DrpTrace(**p), "an LD deviation trace (dirty road patch, modelled)",
    needs=frozenset({Capability.LANE_DETECTOR}), params=_params("drp-trace", DrpTrace)))
ATTACKS.add(Component(
    "drp-bend", lambda p, rng, defense: DrpBend(**p), "an LD deviation trace that also rotates the detected lines",
    needs=frozenset({Capability.LANE_DETECTOR}), params=_params("drp-bend", DrpBend)))
ATTACKS.add(Component(
    "drp-patch", lambda p, rng, defense: DrpPatch(**p), "a dark patch painted on the road the camera sees",
    needs=frozenset({Capability.CAMERA_IMAGE}), params=_params("drp-patch", DrpPatch)))
