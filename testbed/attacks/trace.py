"""Trace injection: a lateral-deviation trace (t, dev) added to the MSF output, as in the paper's simulation
and chassis experiments (§5.3–5.4). The shipped `default` trace is the most aggressive FusionRipper trace
shape: 2 m of lateral deviation 10 s after the attack starts (exponential growth, 4 m at its 12 s end).
"""

from __future__ import annotations

import csv
import math
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from testbed.attacks.base import Attack, AttackerView, shift_pose
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.localization.estimate import LocalizationEstimate

IDLE, INJECTING = "idle", "injecting"


class Trace:
    """A lateral-deviation trace: dev(τ) linearly interpolated, 0 before τ=0, held at its last value after."""

    def __init__(self, t: np.ndarray, dev: np.ndarray, source: str) -> None:
        self.t, self.dev, self.source = t, dev, source

    def __call__(self, tau: float) -> float:
        if tau < self.t[0]:
            return 0.0
        return float(np.interp(tau, self.t, self.dev))

    @classmethod
    def load(cls, path: Path) -> Trace:
        """Read a CSV with header `t,dev` (s, m); raises ValueError naming the file and line on bad input."""
        if not path.is_file():
            raise UserError(f"trace file not found: {path}")
        try:
            with path.open(newline="") as fh:
                rows = list(csv.reader(fh))
        except (UnicodeDecodeError, csv.Error) as exc:
            raise UserError(f"{path}: not a text CSV trace ({exc})") from None
        if not rows or [c.strip() for c in rows[0]] != ["t", "dev"]:
            raise UserError(f"{path}: malformed trace CSV, the first line must be the header 't,dev'")
        ts: list[float] = []
        devs: list[float] = []
        for lineno, row in enumerate(rows[1:], start=2):
            if not row or all(not c.strip() for c in row):
                continue
            try:
                if len(row) != 2:
                    raise ValueError
                t, dev = float(row[0]), float(row[1])
            except ValueError:
                raise UserError(
                    f"{path}:{lineno}: malformed trace CSV row {row!r}, expected two numbers t,dev"
                ) from None
            if not (math.isfinite(t) and math.isfinite(dev)):
                raise UserError(f"{path}:{lineno}: trace values must be finite, got {row!r}")
            if ts and t <= ts[-1]:
                raise UserError(f"{path}:{lineno}: trace times must increase strictly ({t} after {ts[-1]})")
            ts.append(t)
            devs.append(dev)
        if len(ts) < 2:
            raise UserError(f"{path}: a trace needs at least two rows, got {len(ts)}")
        if ts[0] < 0:
            raise UserError(f"{path}: trace times start at 0 (time since attack start), got {ts[0]}")
        return cls(np.array(ts), np.array(devs), str(path))

    @classmethod
    def named(cls, name: str) -> Trace:
        """A trace shipped with the package (testbed/attacks/traces/NAME.csv)."""
        ref = resources.files("testbed.attacks") / "traces" / f"{name}.csv"
        if not ref.is_file():
            shipped = sorted(
                p.name.removesuffix(".csv")
                for p in (resources.files("testbed.attacks") / "traces").iterdir()
                if p.name.endswith(".csv")
            )
            raise UserError(f"unknown trace {name!r}; shipped traces: {shipped} (or give a path to a .csv)")
        with resources.as_file(ref) as path:
            trace = cls.load(Path(path))
        trace.source = name
        return trace


class TraceInjection(Attack):
    """Adds scale·trace(t − start) to the MSF pose along the left normal of the lane heading."""

    name = "trace"
    capabilities = frozenset({ThreatCapability.MSF_OUTPUT})

    def __init__(self, trace: Trace, start: float = 10.0, scale: float = 1.0) -> None:
        super().__init__(start)
        if not math.isfinite(scale):
            raise UserError(f"trace scale must be finite, got {scale}")
        self.trace, self.scale = trace, scale
        self.offset = 0.0
        self.stage = IDLE

    def tamper_msf(self, est: LocalizationEstimate, view: AttackerView) -> LocalizationEstimate:
        if view.t < self.start_time:
            self.stage, self.offset = IDLE, 0.0
            return est
        self.stage = INJECTING
        self.offset = self.scale * self.trace(view.t - self.start_time)
        return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, self.offset), est.cov)

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name, "trace": self.trace.source, "start": self.start_time, "scale": self.scale}
