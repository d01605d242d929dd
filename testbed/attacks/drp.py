"""LD-side attacks modelled on the Dirty Road Patch (DRP) attack (Sato et al. 2021; paper §6.2).

`DrpTrace` injects a lateral deviation into the lane detector's output: from `start` the detected lines
shift so that the LD deviation moves by `shift` (m, + left), ramping in over `ramp` seconds and lasting
`duration` seconds (the car drives over the patch). Shifting the ego-lane centre right by s makes the car
appear s further left, so both lines' c0 move by −s. `DrpBend` does the same and also rotates the detected
lines by `bend` (rad, + left) with the same ramp, so that a response steering by the lines' slope is steered
by it; `DrpCreep` ramps both over many seconds, so that they stay under the checks while the defense carries
what they turned. `DrpPatch` paints a physical dirty-road patch into the road texture, which the camera sees and the
detector reacts to on its own.
"""

from __future__ import annotations

import math
from typing import Any

from testbed.attacks.base import Attack, AttackerView, shift_lines
from testbed.attacks.threat import ThreatCapability
from testbed.errors import UserError
from testbed.lane_detection import LaneDetection

IDLE, ACTIVE, OVER, PAINTED = "idle", "active", "over", "painted"


def _check(cond: bool, msg: str) -> None:
    if not cond:
        raise UserError(msg)


class DrpTrace(Attack):
    """Trapezoid LD-deviation injection: ramp to `shift` in `ramp` s, hold, stop after `duration` s."""

    name = "drp-trace"
    capabilities = frozenset({ThreatCapability.LD_OUTPUT})

    def __init__(
        self, start: float = 10.0, shift: float = 0.7, ramp: float = 1.0, duration: float = 5.0
    ) -> None:
        super().__init__(start)
        _check(math.isfinite(shift), f"drp-trace shift must be finite, got {shift}")
        _check(math.isfinite(ramp) and ramp >= 0, f"drp-trace ramp must be a time >= 0 s, got {ramp}")
        _check(math.isfinite(duration) and duration > 0, f"drp-trace duration must be > 0 s, got {duration}")
        self.shift, self.ramp, self.duration = shift, ramp, duration
        self.stage = IDLE
        self.offset = 0.0

    def injected(self, t: float) -> float:
        """LD deviation added at time t (m, + left)."""
        return self.shift * self.ramp_fraction(t)

    def ramp_fraction(self, t: float) -> float:
        """Trapezoid profile in [0, 1]: 0 outside the attack, ramping to 1 over `ramp` seconds."""
        tau = t - self.start_time
        if tau < 0 or tau > self.duration:
            return 0.0
        return 1.0 if self.ramp == 0 else min(1.0, tau / self.ramp)

    def tamper_ld(self, ld: LaneDetection, view: AttackerView) -> LaneDetection:
        tau = view.t - self.start_time
        self.stage = IDLE if tau < 0 else (ACTIVE if tau <= self.duration else OVER)
        self.offset = self.injected(view.t)
        slope = self._slope(view.t)
        if self.offset == 0.0 and slope == 0.0:
            return ld
        return shift_lines(ld, self.offset, slope)

    def _slope(self, t: float) -> float:
        """Added to the lines' c1 at time t (none for a pure deviation trace)."""
        return 0.0

    def state(self) -> dict[str, Any]:
        return {"stage": self.stage, "switch_time": None, "offset": self.offset}

    def describe(self) -> dict[str, Any]:
        return {
            "kind": self.name,
            "start": self.start_time,
            "shift": self.shift,
            "ramp": self.ramp,
            "duration": self.duration,
        }


class DrpBend(DrpTrace):
    """`DrpTrace` plus a rotation of the detected lines by `bend` (rad, + left), ramped alike: the shift
    raises the alarm, the bend then acts on a response that takes its heading from the lines."""

    name = "drp-bend"

    def __init__(self, start: float = 10.0, shift: float = 0.7, bend: float = -0.1, ramp: float = 1.0,
                 duration: float = 10.0) -> None:
        super().__init__(start, shift, ramp, duration)
        _check(math.isfinite(bend) and 0.0 < abs(bend) < math.pi / 4,
               f"drp-bend bend must be a non-zero angle below pi/4 rad, got {bend}")
        self.bend = bend

    def _slope(self, t: float) -> float:
        return math.tan(self.bend * self.ramp_fraction(t))

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "bend": self.bend}


class DrpCreep(DrpBend):
    """`DrpBend` ramped slowly: the lines bent under the heading check and shifted under b for many seconds, then
    past b (a search family of its own: `drp-bend`'s ramps end at 3 s)."""

    name = "drp-creep"


class DrpPatch(Attack):
    """A dark patch painted on the road at arc length `at`, offset `offset` from the reference line."""

    name = "drp-patch"
    capabilities = frozenset({ThreatCapability.ROAD_PAINT})

    def __init__(
        self,
        at: float,
        length: float = 10.0,
        width: float = 1.5,
        offset: float = 0.0,
        angle: float = 0.0,
        darkness: float = 0.5,
    ) -> None:
        super().__init__(0.0)
        _check(math.isfinite(at) and at >= 0, f"drp-patch at must be an arc length >= 0 m, got {at}")
        _check(math.isfinite(length) and length > 0, f"drp-patch length must be > 0 m, got {length}")
        _check(math.isfinite(width) and width > 0, f"drp-patch width must be > 0 m, got {width}")
        _check(math.isfinite(offset), f"drp-patch offset must be finite, got {offset}")
        _check(math.isfinite(angle), f"drp-patch angle must be finite (rad), got {angle}")
        _check(0.0 < darkness <= 1.0, f"drp-patch darkness must be in (0, 1], got {darkness}")
        self.at, self.length, self.width, self.offset = at, length, width, offset
        self.angle, self.darkness = angle, darkness

    def painters(self) -> list[Any]:
        from tracks.paint import PatchPainter

        return [
            PatchPainter(
                s_center=self.at,
                t_center=self.offset,
                length=self.length,
                width=self.width,
                angle=self.angle,
                darkness=self.darkness,
            )
        ]

    def state(self) -> dict[str, Any]:
        return {"stage": PAINTED, "switch_time": None, "offset": 0.0}

    def describe(self) -> dict[str, Any]:
        return {
            "kind": self.name,
            "at": self.at,
            "length": self.length,
            "width": self.width,
            "offset": self.offset,
            "angle": self.angle,
            "darkness": self.darkness,
        }
