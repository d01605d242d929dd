"""Defense parameters: the scenario TOML `[defense]` table, validated.

Defaults follow the paper where it gives a number: CUSUM b = 0.6, τ = 0.1 (§5.2), AR deceleration
4 m/s² (§4.3). The paper gives no window size w or weight λ for Alg. 4; λ = 0.8 is this testbed's choice,
and w is set with the response options below.

LD3's open choices in the attack response: `heading` of the fused pose (Alg. 2 does not say which),
`window`, `r_power` and `p_source` (where Alg. 4's P^MSF and P^LD come from). `PAPER_MODE` is the paper's
system as written (MSF heading, constant P, a 1-s window); the defaults are what the ablation campaign
measured to hold best on held-out roads (docs/decisions.md): the fused heading clamped to 0.02 rad and a
5-detection window.

NaiveAR's "maximum deceleration" (§5.3) is 4.5 m/s²: the paper models NaiveAR on Baidu Apollo's in-lane
stop, and Apollo's planner never commands more braking than its longitudinal acceleration lower bound,
`FLAGS_longitudinal_acceleration_lower_bound = -4.5` m/s² (modules/planning/common/planning_gflags.cc).
The car's own brake limit (8 m/s² for the sedan) is what the actuator can do, not what an AD planner
asks for in an emergency in-lane stop, so it is not NaiveAR's deceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

HEADINGS = ("msf", "lane", "ld", "fused")
"""Heading of the fused pose: the MSF yaw, the lane heading, or the lane heading corrected by the
detected lines' slope at x = 0 (clamped to ±heading_clamp), or the mean of the MSF's and the lines' weighed
by the fusion's uncertainties (testbed.defense.fused_heading)."""
P_SOURCES = ("constant", "reported")
"""Alg. 4's P: the constants p_msf / p_ld, or the MSF's lateral variance and the detector's c0 variance."""
_CHOICES: dict[str, tuple[str, ...]] = {"heading": HEADINGS, "p_source": P_SOURCES}

# (check, message) per field; every check takes the already type-checked value.
_RULES: dict[str, tuple[Any, str]] = {
    "heading": (lambda v: v in HEADINGS, f"must be one of {HEADINGS}"),
    "heading_clamp": (lambda v: 0.0 < v <= 0.5, "must lie in (0, 0.5] rad"),
    "p_source": (lambda v: v in P_SOURCES, f"must be one of {P_SOURCES}"),
    "r_power": (lambda v: 0.5 <= v <= 4.0, "must lie in [0.5, 4]"),
    "b": (lambda v: v >= 0.0, "must be >= 0"),
    "tau": (lambda v: v >= 0.0, "must be >= 0"),
    "window": (lambda v: v >= 1, "must be an integer >= 1"),
    "lam": (lambda v: 0.0 <= v <= 1.0, "must lie in [0, 1]"),
    "p_msf": (lambda v: v > 0.0, "must be > 0"),
    "p_ld": (lambda v: v > 0.0, "must be > 0"),
    "kf_q": (lambda v: v >= 0.0, "must be >= 0"),
    "kf_p0": (lambda v: v > 0.0, "must be > 0"),
    "ar_decel": (lambda v: v > 0.0, "must be > 0"),
    "max_decel": (lambda v: v > 0.0, "must be > 0"),
    "existence_threshold": (lambda v: 0.0 <= v <= 1.0, "must lie in [0, 1]"),
    "savior_b": (lambda v: v >= 0.0, "must be >= 0"),
    "savior_tau": (lambda v: v >= 0.0, "must be >= 0"),
    "savior_speed_std": (lambda v: v > 0.0, "must be > 0"),
    "savior_accel_std": (lambda v: v > 0.0, "must be > 0"),
    "savior_yaw_rate_std": (lambda v: v > 0.0, "must be > 0"),
}


@dataclass(frozen=True)
class DefenseConfig:
    """LD3 detection (b, tau), safety-driven fusion (window, lam, p_*, kf_*), response decelerations,
    LD line validity, and the SAVIOR baseline's CUSUM and EKF noise. SI units."""

    b: float = 0.6
    """CUSUM weight on |D_MSF - D_LD| (m)."""
    tau: float = 0.1
    """CUSUM alarm threshold (m)."""
    window: int = 5
    """Alg. 4 deviation-history window w (lane detections); the paper mode's is 20 (1 s at 20 Hz)."""
    lam: float = 0.8
    """Alg. 4 weight λ of the deviation-history uncertainty against the sources' own."""
    p_msf: float = 0.1
    """P^MSF: MSF's own lateral uncertainty fed to Alg. 4 (m²)."""
    p_ld: float = 0.1
    """P^LD: LD's own lateral uncertainty fed to Alg. 4 (m²)."""
    r_power: float = 1.0
    """Exponent k on Alg. 4's history term: R = λ f^k + (1 − λ) P (the paper: k = 1)."""
    p_source: str = "constant"
    """Where P^MSF and P^LD come from (`P_SOURCES`)."""
    heading: str = "fused"
    """Heading of the fused pose in attack response (`HEADINGS`); the paper mode is "msf"."""
    heading_clamp: float = 0.02
    """Largest |heading relative to the lane| the "ld" and "fused" headings take from the detected lines (rad)."""
    kf_q: float = 0.05
    """Process noise of the 1-D fusion Kalman filter, added on each predict (m²)."""
    kf_p0: float = 1.0
    """Initial variance of the 1-D fusion Kalman filter at AR onset (m²); its state starts at d = 0."""
    ar_decel: float = 4.0
    """LD3 (and SAVIOR) attack-response deceleration (m/s²)."""
    max_decel: float = 4.5
    """NaiveAR's maximum deceleration (m/s²): Apollo's planner lower bound (module docstring)."""
    existence_threshold: float = 0.5
    """A detected lane line with existence probability below this is not valid."""
    savior_b: float = 1.0
    """SAVIOR CUSUM weight on the GNSS residual (m)."""
    savior_tau: float = 3.0
    """SAVIOR CUSUM threshold (m)."""
    savior_speed_std: float = 0.1
    """SAVIOR EKF: wheel-speed measurement noise (m/s)."""
    savior_accel_std: float = 0.5
    """SAVIOR EKF: longitudinal process noise (m/s²)."""
    savior_yaw_rate_std: float = 0.05
    """SAVIOR EKF: yaw-rate process noise (rad/s)."""

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DefenseConfig:
        """Build from a TOML table; unknown keys and bad values raise ValueError naming the key."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown [defense] keys {unknown}; allowed: {sorted(known)}")
        values: dict[str, Any] = {}
        for key, raw in d.items():
            value = _coerce(key, raw)
            check, message = _RULES[key]
            if not check(value):
                raise ValueError(f"[defense] {key} = {raw!r} {message}")
            values[key] = value
        config = cls(**values)
        if "heading_clamp" in values and config.heading not in ("ld", "fused"):
            raise ValueError(f"[defense] heading_clamp acts only with heading = 'ld' or 'fused', not "
                             f"{config.heading!r}: drop it or set the heading")
        return config


PAPER_MODE: dict[str, Any] = {"heading": "msf", "window": 20, "p_source": "constant", "r_power": 1.0}
"""The `[defense]` overrides that give LD3 as the paper specifies it: Alg. 2 with the MSF yaw, Alg. 4 with
constant P and f to the first power, over a 1-s window."""


def _coerce(key: str, raw: Any) -> float | int | str:
    if key in _CHOICES:
        if not isinstance(raw, str):
            raise ValueError(f"[defense] {key} must be one of {_CHOICES[key]}, got {raw!r}")
        return raw
    if isinstance(raw, bool):
        raise ValueError(f"[defense] {key} must be a number, got a boolean")
    if key == "window":
        if not isinstance(raw, int):
            raise ValueError(f"[defense] window must be an integer, got {raw!r}")
        return raw
    if not isinstance(raw, int | float) or not math.isfinite(raw):
        raise ValueError(f"[defense] {key} must be a finite number, got {raw!r}")
    return float(raw)
