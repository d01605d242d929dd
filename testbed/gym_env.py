"""A Gymnasium environment for worst-case attack search: `ld3/Lateral-v0`.

The agent is the attacker. Each step it chooses a lateral GNSS spoofing offset (m, + left of the lane,
within ±max_offset), which every GNSS fix until the next step carries; the simulation then runs
`ticks_per_step` control ticks (by default those of 0.1 s, one GNSS fix at 10 Hz). Its observation is what a tailgating
attacker sees: [t (s), the victim's physical lateral deviation (m, + left), speed (m/s), the offset now in
force (m)]. The reward is the victim's |physical deviation| after the step; the episode ends with the run
(a consequence, a stop, the end of the road or the duration), and `info` carries the summary then.

    import gymnasium, testbed.gym_env
    env = gymnasium.make("ld3/Lateral-v0", scenario="local", defense="ld3")
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from testbed.api import Simulation, scenario
from testbed.attacks.base import Attack, AttackerView, left_normal
from testbed.errors import UserError
from testbed.localization.sensors import GnssFix

STEP_S = 0.1
"""The default step: one fix of the 10 Hz GNSS."""


class PolicySpoofer(Attack):
    """GNSS spoofing by a sideways offset that the environment sets each step."""

    name = "policy"

    def __init__(self) -> None:
        super().__init__(0.0)
        self.offset = 0.0
        self.last_view: AttackerView | None = None

    def spoof_gnss(self, fix: GnssFix, view: AttackerView) -> GnssFix:
        self.last_view = view
        if self.offset == 0.0:
            return fix
        return dataclasses.replace(fix, xy=fix.xy + self.offset * left_normal(view.lane_heading))

    def state(self) -> dict[str, Any]:
        return {"stage": "policy", "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {"kind": self.name}


class LateralAttackEnv(gymnasium.Env):
    """The attacker's side of one scenario (module docstring); `reset(seed=...)` sets the scenario seed."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, scenario_name: str = "local", *, defense: str = "ld3", detector: str = "oracle",
                 max_offset: float = 3.0, ticks_per_step: int | None = None, **overrides: Any) -> None:
        if max_offset <= 0 or (ticks_per_step is not None and ticks_per_step < 1):
            raise UserError(f"need max_offset > 0 and ticks_per_step >= 1, got {max_offset}, {ticks_per_step}")
        self.base = scenario(scenario_name, defense=defense, detector=detector, localization="msf", **overrides)
        self.max_offset = max_offset
        self.ticks_per_step = (max(1, round(STEP_S * self.base.rates.control_hz)) if ticks_per_step is None
                               else ticks_per_step)
        self.action_space = spaces.Box(-max_offset, max_offset, shape=(1,), dtype=np.float32)
        high = np.array([self.base.duration + 1.0, 10.0, 100.0, max_offset], dtype=np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self._sim: Simulation | None = None
        self._spoofer = PolicySpoofer()

    def _observation(self, t: float, phys_dev: float | None, speed: float) -> np.ndarray:
        dev = 0.0 if phys_dev is None else phys_dev
        return np.array([t, dev, speed, self._spoofer.offset], dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.close()
        sc = self.base if seed is None else self.base.with_overrides(seed=seed)
        self._spoofer = PolicySpoofer()
        self._sim = Simulation(sc, attack=self._spoofer)
        rec = self._sim.step()
        return self._observation(rec.t, rec.phys_dev, rec.speed), {}

    def step(self, action):
        if self._sim is None:
            raise RuntimeError("call reset() first")
        self._spoofer.offset = float(np.clip(np.asarray(action, dtype=float).ravel()[0], -self.max_offset,
                                             self.max_offset))
        rec = None
        for _ in range(self.ticks_per_step):
            if self._sim.done:
                break
            rec = self._sim.step()
        if rec is None:
            raise RuntimeError("the episode is over; call reset()")
        terminated = self._sim.done
        info = {"summary": self._sim.result().summary} if terminated else {}
        reward = abs(rec.phys_dev) if rec.phys_dev is not None else 0.0
        return self._observation(rec.t, rec.phys_dev, rec.speed), float(reward), terminated, False, info

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None


gymnasium.register(id="ld3/Lateral-v0", entry_point="testbed.gym_env:LateralAttackEnv")
