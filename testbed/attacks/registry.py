"""The attack registry: built-in attacks and the `ld3.attacks` entry points.

Each entry records the threat capabilities its attack acts through and, for the worst-case search, the
space of its parameters (`testbed.attacks.space`).

An attack component's factory is `factory(params, rng, defense)`: the parameters the scenario gives,
validated by the component's `params` model (built from the attack's constructor), the run's attack
random stream, and what it may know of the defense (an object with CUSUM `b` and `tau`). `needs` says
what the run must provide for the attack to act at all.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field, create_model

from testbed.attacks.along import AlongShift
from testbed.attacks.bound_replay import BoundReplay
from testbed.attacks.burst import PROFILES, BurstAttack
from testbed.attacks.coordinated import CoordinatedShift
from testbed.attacks.drp import DrpBend, DrpCreep, DrpPatch, DrpTrace
from testbed.attacks.fusionripper import FusionRipper
from testbed.attacks.gnss_drift import GnssDrift
from testbed.attacks.heading import HeadingBias
from testbed.attacks.offmap import OffMapAttack
from testbed.attacks.response import CUES, POLICIES, ResponsePhaseAttack
from testbed.attacks.shadow import ShadowAttack
from testbed.attacks.space import SIDE, START, ChoiceDim, Dim, FloatDim, IntDim
from testbed.attacks.stealthy import CusumKnowledge, StealthyAttack
from testbed.attacks.strike import StrikeAttack
from testbed.attacks.trace import Trace, TraceInjection
from testbed.attacks.unchecked import UncheckedTicks
from testbed.attacks.zone import ZONES, ZoneAttack
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
    "zone": "road feature the attack is timed to: intersection or curve",
    "index": "which occurrence of the zone after start (0 = the first)",
    "lateral": "lateral offset of the MSF pose (m, + left)",
    "hold": "time the offset is held after the zone before it ramps out (s)",
    "along": "longitudinal shift of the MSF pose along the lane (m, + ahead)",
    "yaw": "yaw bias added to the MSF pose (rad, + left)",
    "lead": "time before the alarm is forced, over which the along shift ramps in (s)",
    "force": "sideways jump of the MSF pose that forces the alarm (m, + left)",
    "cue": "how the attacker learns of the alarm: observed (the victim brakes) or timed",
    "delay": "timed cue: time after the jump the response is assumed to run (s)",
    "policy": "the MSF pose in the response: offmap, centre, opposite or hold",
    "hspend": "fraction of the heading check's threshold spent",
    "hsustain": "yaw bias held after the spend, as a fraction of the heading check's weight",
    "cancel": "take the MSF's own error (seen against the true pose) out of what is sent",
    "k_sigma": "benign residual noise granted to the attacker, in σ of the measured residual (0: none)",
    "kappa": "curvature above which the road counts as a curve (1/m)",
    "distance": "lateral distance the MSF pose is moved (m, + left)",
    "spend": "fraction of the CUSUM threshold τ the burst spends",
    "profile": "burst shape: flat, rise or fall",
    "sustain": "offset (residual) held after the spend, as a fraction of b",
    "bias": "heading bias added to the MSF yaw (rad, + left)",
    "rate": "lateral drift rate (m/s)", "limit": "largest lateral offset (m)",
    "lidar_below": "the drift begins once the LiDAR feature quality is below this (0..1; > 1: at start)",
}


def _params(name: str, cls: type, skip: tuple[str, ...] = (), **extra: Any) -> type[Params]:
    """The attack's parameter model: its constructor's keywords (less `skip`), plus `extra` fields."""
    base = params_from_signature(f"{name}-params", cls.__init__, skip, _DESCRIPTIONS)
    fields = {k: (typ, Field(default, description=_DESCRIPTIONS.get(k))) for k, (typ, default) in extra.items()}
    return create_model(f"{name}-params", __base__=base, **fields) if fields else base


def _component(cls: type, help_text: str, factory, *, skip: tuple[str, ...] = (), space: tuple[Dim, ...] = (),
               needs: frozenset[Capability] = frozenset(), **extra: Any) -> Component:
    """The registry entry of attack class `cls`: its name and capabilities come from the class."""
    return Component(cls.name, factory, help_text, needs=needs, params=_params(cls.name, cls, skip, **extra),
                     capabilities=frozenset(c.value for c in cls.capabilities), space=space)


_MSF = frozenset({Capability.GNSS})
_LD = frozenset({Capability.LANE_DETECTOR})
ATTACKS: Registry[Component] = Registry("attack kind", Component, "ld3.attacks")
ATTACKS.add(_component(
    FusionRipper, "FusionRipper: lateral GNSS spoofing, profiling then aggressive",
    lambda p, rng, defense: FusionRipper(**p, rng=rng), skip=("rng",), needs=_MSF,
    space=(START, FloatDim("d", 0.3, 3.0), FloatDim("f", 1.05, 2.0), SIDE)))
ATTACKS.add(_component(
    TraceInjection, "a recorded lateral-deviation trace injected into the localization output",
    lambda p, rng, defense: TraceInjection(_resolve_trace(p.pop("trace", "default")), **p), skip=("trace",),
    trace=(str, "default"), space=(START, FloatDim("scale", -1.5, 1.5))))
ATTACKS.add(_component(
    StealthyAttack, "white-box MSF offset kept just under LD3's CUSUM threshold", _stealthy, skip=("knowledge",),
    b=(float | None, None), tau=(float | None, None), ld_std=(float | None, None),
    space=(START, FloatDim("margin", 0.0, 0.3), FloatDim("spread", 0.0, 5.0), SIDE)))
ATTACKS.add(_component(
    DrpTrace, "an LD deviation trace (dirty road patch, modelled)", lambda p, rng, defense: DrpTrace(**p),
    needs=_LD, space=(START, FloatDim("shift", -2.0, 2.0), FloatDim("ramp", 0.0, 3.0),
                      FloatDim("duration", 1.0, 20.0))))
ATTACKS.add(_component(
    DrpBend, "an LD deviation trace that also rotates the detected lines", lambda p, rng, defense: DrpBend(**p),
    needs=_LD, space=(START, FloatDim("shift", -2.0, 2.0), FloatDim("bend", -0.3, 0.3),
                      FloatDim("ramp", 0.0, 3.0), FloatDim("duration", 1.0, 20.0))))
ATTACKS.add(_component(
    DrpCreep, "an LD deviation trace and rotation of the detected lines ramped over many seconds",
    lambda p, rng, defense: DrpCreep(**p),
    needs=_LD, space=(START, FloatDim("shift", -1.5, 1.5), FloatDim("bend", -0.04, 0.04),
                      FloatDim("ramp", 3.0, 25.0), FloatDim("duration", 5.0, 35.0))))
ATTACKS.add(_component(
    DrpPatch, "a dark patch painted on the road the camera sees", lambda p, rng, defense: DrpPatch(**p),
    needs=frozenset({Capability.CAMERA_IMAGE})))
ATTACKS.add(_component(
    ZoneAttack, "adaptive: MSF offset timed to an intersection or a curve, where detection is gated or weak",
    lambda p, rng, defense: ZoneAttack(**p),
    space=(FloatDim("start", 0.0, 30.0), ChoiceDim("zone", ZONES), IntDim("index", 0, 2),
           FloatDim("lateral", -3.5, 3.5), FloatDim("ramp", 0.01, 3.0, log=True), FloatDim("hold", 0.0, 20.0),
           FloatDim("along", -25.0, 25.0))))
ATTACKS.add(_component(
    OffMapAttack, "adaptive: the MSF pose moved off the mapped road (ramped or in one tick)",
    lambda p, rng, defense: OffMapAttack(**p),
    space=(START, FloatDim("distance", -40.0, 40.0), FloatDim("ramp", 0.01, 3.0, log=True))))
ATTACKS.add(_component(
    HeadingBias, "adaptive: the MSF yaw biased with its position left true (Alg. 1 checks positions only)",
    lambda p, rng, defense: HeadingBias(**p),
    space=(START, FloatDim("bias", -0.15, 0.15), FloatDim("ramp", 0.01, 5.0, log=True))))
ATTACKS.add(_component(
    BurstAttack, "adaptive: spends LD3's CUSUM budget τ in a shaped burst, then holds under b",
    lambda p, rng, defense: BurstAttack(**p),
    space=(START, FloatDim("spend", 0.2, 1.2), FloatDim("spread", 0.05, 5.0), ChoiceDim("profile", PROFILES),
           FloatDim("sustain", 0.0, 1.2), SIDE)))
ATTACKS.add(_component(
    CoordinatedShift, "adaptive: MSF pose and detected lines shifted together (outside LD3's threat model)",
    lambda p, rng, defense: CoordinatedShift(**p), needs=_LD,
    space=(START, FloatDim("rate", 0.1, 2.0), FloatDim("limit", 0.5, 4.0), SIDE)))
ATTACKS.add(_component(
    GnssDrift, "adaptive: slow lateral GNSS drift begun where the LiDAR locator is weak",
    lambda p, rng, defense: GnssDrift(**p), needs=_MSF,
    space=(START, FloatDim("rate", 0.05, 2.0), FloatDim("limit", 0.5, 6.0), FloatDim("lidar_below", 0.2, 1.01),
           SIDE)))
ATTACKS.add(_component(
    UncheckedTicks, "adaptive: the MSF pose moved only on control ticks that carry no lane detection",
    lambda p, rng, defense: UncheckedTicks(**p),
    space=(START, FloatDim("lateral", -3.5, 3.5), FloatDim("yaw", -0.2, 0.2), FloatDim("ramp", 0.01, 3.0, log=True))))
ATTACKS.add(_component(
    AlongShift, "adaptive: the MSF pose moved along the lane, its lateral offset and relative heading kept",
    lambda p, rng, defense: AlongShift(**p),
    space=(START, FloatDim("along", -30.0, 30.0), FloatDim("ramp", 0.01, 5.0, log=True))))
ATTACKS.add(_component(
    ResponsePhaseAttack, "adaptive: forces the alarm, then moves the MSF pose against the response",
    lambda p, rng, defense: ResponsePhaseAttack(**p),
    space=(START, FloatDim("along", -30.0, 30.0), FloatDim("lead", 0.05, 5.0, log=True),
           FloatDim("force", -3.5, 3.5), FloatDim("yaw", -0.2, 0.2), ChoiceDim("cue", CUES),
           FloatDim("delay", 0.05, 3.0, log=True), ChoiceDim("policy", POLICIES))))
ATTACKS.add(_component(
    StrikeAttack, "adaptive: spends the lateral and the heading CUSUM budgets together at speed",
    lambda p, rng, defense: StrikeAttack(**p),
    space=(START, FloatDim("spend", 0.2, 1.2), FloatDim("hspend", 0.2, 1.2), FloatDim("spread", 0.05, 3.0, log=True),
           FloatDim("sustain", 0.0, 1.2), FloatDim("hsustain", 0.0, 1.2), SIDE)))
ATTACKS.add(_component(
    BoundReplay, "adaptive: replays the worst attack of the deviation bound's linear program on the victim's loop",
    lambda p, rng, defense: BoundReplay(**p),
    space=(START, FloatDim("scale", 0.5, 1.2), ChoiceDim("cancel", (True, False)), SIDE)))
ATTACKS.add(_component(
    ShadowAttack, "adaptive: runs a shadow of LD3's CUSUMs and spends their budgets closed-loop, the MSF's own error "
    "cancelled", lambda p, rng, defense: ShadowAttack(**p),
    space=(START, FloatDim("spend", 0.2, 1.2), FloatDim("sustain", 0.5, 1.2), FloatDim("hspend", 0.2, 1.2),
           FloatDim("hsustain", 0.5, 1.2), FloatDim("spread", 0.05, 3.0, log=True), FloatDim("along", -1.0, 1.0),
           SIDE)))
