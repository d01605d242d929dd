"""Lane tracker: a Kalman filter over the two ego lines' cubics, predicted with the car's own odometry.

State: the left and right lines' offsets c0 and their shared c1, c2, c3 (heading, half curvature, a sixth of
the curvature rate; the lines of a lane are parallel), in the vehicle frame. Between frames the car advances
dx = v·dt and turns dψ = r·dt (wheel speed and yaw rate from the chassis, trapezoid over the interval; never
GNSS or the MSF), so each line becomes y'(x) = y(x + dx) − dψ·x − dx·dψ/2: the lateral motion relative to the
lane comes from the tracked heading, not from smoothing toward the past. Process noise: lateral motion the
odometry misses (slip) moves both offsets together, yaw-rate error and road curvature changes act on the
shared terms, lane-width changes on each offset alone; so one seen line carries the other.
A present detected line updates the filter with its cubic's values at the `measure_at` distances ahead, noise
`range_std` divided by its existence probability, replaced by the detector's `left_var` / `right_var` when reported,
else by the line's running residual variance (floored at `min_offset_std`²): a line that keeps disagreeing with
the rest, such as worn paint, counts for less. A camera reads a line best some metres ahead, and its fit's offset
and slope at the car are extrapolations, while the odometry carries what was read ahead to the car. With no
`measure_at` distances it updates the filter with the cubic's coefficients instead (noise `measurement_std`, c0's
variance replaced the same way and the others in proportion). A line whose offset innovation (at the first of those
distances with `measure_at`) exceeds `gate` standard deviations is left out; both lines jumping together is the car
moving (accepted at once); the only seen line off for `confirm_frames` frames in a row is the car moving, one line off
while the other stays for `width_confirm_frames` is the lane's width changing (accepted then); any jump
only where the jumped lines' heading agrees with the tracked one (a car moved sideways keeps its heading to
the lane, which the gyro carries; a line read off the wrong paint seldom does). A detection left out does
not count as seen.
A track starts on one detected line, or on two a lane's width apart (`lane_width_range`).
Lines are re-associated when the car crosses one (left becomes right, and the next line over is predicted
one lane width further), only a line predicted within `cross_margin` of the car. A line not seen for
`max_coast` seconds is no longer output; an output line carries its last detected existence probability, and the
filter's c0 variance where the detector reports its own.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from filterpy.kalman import KalmanFilter

from testbed.lane_detection import LaneDetection

LEFT, RIGHT = 0, 1
N = 4  # coefficients per line
NOMINAL_LANE_WIDTH = 3.5  # m: where an unseen line is first placed, with `unseen_std` around it


@dataclass(frozen=True)
class TrackerParams:
    """Noise model and gating of `LaneTracker` (SI units; process noises per √s or per √m travelled)."""

    measurement_std: tuple[float, float, float, float] = (0.20, 0.02, 1e-3, 3e-5)
    """Std of a detected line's c0..c3 at existence probability 1, before the reported or residual variance
    replaces c0's."""
    lateral_std: float = 0.03
    """m/√s: lateral motion of the car the odometry does not see (slip), common to both lines."""
    yaw_rate_std: float = 0.003
    """rad/s: yaw-rate error, common to both lines' heading."""
    curvature_std: float = 1e-5
    """1/m per √m: random walk of c2 (road curvature changes), common to both lines, fed the coefficients."""
    ahead_curvature_std: float = 1e-3
    """1/m per √m: the same measured ahead, where the values ahead see a curve's start (an arc drawn without a
    clothoid, as public maps often are) at once and the shape must follow it."""
    curvature_rate_std: float = 1e-5
    """1/m² per √m: random walk of c3, common to both lines."""
    width_std: float = 0.005
    """m per √m: random walk of each line's own offset (lane width changes)."""
    unseen_std: float = 1.0
    """m: c0 std of a line placed from the other one, never seen yet."""
    gate: float = 3.5
    """Offset innovations beyond this many standard deviations are outliers."""
    confirm_frames: int = 2
    """Consecutive outlier frames after which the only seen line's jump is taken as the car's motion."""
    width_confirm_frames: int = 6
    """Consecutive outlier frames after which one line's jump, the other line seen where it was, is taken as
    the lane's width changing."""
    max_coast: float = 1.0
    """s a line is output after it was last seen."""
    min_existence: float = 0.05
    """A detected line with a lower existence probability does not update the filter."""
    adapt_rate: float = 0.02
    """Per frame weight of the newest squared residual in a line's running residual variance (0: no adaption)."""
    min_offset_std: float = 0.03
    """m: floor of the adapted c0 noise std."""
    measure_at: tuple[float, ...] = (0.0, 6.0, 8.0, 10.0, 12.0)
    """m ahead of the car, increasing: where a detected line is measured (its cubic's value); (): its coefficients."""
    lane_width_range: tuple[float, float] = (2.5, 5.0)
    """m: the widths a lane can have; a line taken up (not seen within `max_coast`) that would put the lane's width
    outside them, against the other line as tracked, is left out, and two lines that are not that far apart start
    no track."""
    range_std: float = 0.08
    """m: std of a detected line's value at each `measure_at` distance at existence probability 1, before the
    reported or residual variance replaces it."""
    cross_margin: float = 0.5
    """m: the car crosses a line (left and right re-associated) only where the line's predicted offset at the car is
    within this of it or past it; a line farther off is not crossed within a frame, whatever a misread suggests."""

    def __post_init__(self) -> None:
        checks = [
            (len(self.measurement_std) == N and all(s > 0 for s in self.measurement_std),
             "measurement_std needs 4 positive values (c0..c3)"),
            (min(self.lateral_std, self.yaw_rate_std, self.curvature_std, self.ahead_curvature_std,
                 self.curvature_rate_std, self.width_std) >= 0, "process noise stds must be >= 0"),
            (self.unseen_std > 0 and self.gate > 0, "unseen_std and gate must be > 0"),
            (self.confirm_frames >= 1 and self.width_confirm_frames >= 1,
             "confirm_frames and width_confirm_frames must be >= 1"),
            (self.max_coast >= 0, "max_coast must be >= 0 s"),
            (0.0 <= self.min_existence < 1.0, "min_existence must be in [0, 1)"),
            (0.0 <= self.adapt_rate <= 1.0, "adapt_rate must be in [0, 1]"),
            (not self.measure_at or (len(self.measure_at) >= 2 and self.measure_at[0] >= 0.0
                                     and all(b > a for a, b in itertools.pairwise(self.measure_at))
                                     and all(math.isfinite(x) for x in self.measure_at)),
             f"measure_at needs at least 2 finite increasing distances >= 0 m, or none (got {list(self.measure_at)})"),
            (self.range_std > 0.0, "range_std must be > 0"),
            (self.cross_margin >= 0.0, "cross_margin must be >= 0 m"),
            (len(self.lane_width_range) == 2 and 0.0 < self.lane_width_range[0] < self.lane_width_range[1],
             f"lane_width_range needs 0 < min < max m (got {list(self.lane_width_range)})"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"tracker: {msg}")


def shift_matrix(dx: float) -> np.ndarray:
    """(4, 4) F with F @ c = the coefficients of y(x + dx) for y = c0 + c1 x + c2 x² + c3 x³."""
    return np.array([[1.0, dx, dx**2, dx**3],
                     [0.0, 1.0, 2 * dx, 3 * dx**2],
                     [0.0, 0.0, 1.0, 3 * dx],
                     [0.0, 0.0, 0.0, 1.0]])


DIM = 5  # state: left offset, right offset, then the shared c1, c2, c3
_OFFSET = (0, 1)
_SHARED = slice(2, DIM)
_E = np.eye(DIM)
_COMMON_OFFSET = _E[0] + _E[1]
_SELECT = [np.vstack([_E[side], _E[2:]]) for side in (LEFT, RIGHT)]
"""H of one line: its cubic (c0 its own offset, c1..c3 shared) from the state."""
_SWAP_LEFT = np.block([[np.array([[2.0, -1.0], [1.0, 0.0]]), np.zeros((2, 3))], [np.zeros((3, 2)), np.eye(3)]])
"""The car crossed its left line: the new right line is the old left, the new left one lane width further."""
_SWAP_RIGHT = np.block([[np.array([[0.0, 1.0], [-1.0, 2.0]]), np.zeros((2, 3))], [np.zeros((3, 2)), np.eye(3)]])
"""The car crossed its right line."""


def transition(dx: float) -> np.ndarray:
    """(5, 5) state transition for `dx` metres of travel: both lines shifted along x (`shift_matrix`)."""
    f = np.zeros((DIM, DIM))
    sm = shift_matrix(dx)
    f[np.ix_([0, 2, 3, 4], [0, 2, 3, 4])] = sm
    f[np.ix_([1, 2, 3, 4], [1, 2, 3, 4])] = sm
    return f


class Measurement(NamedTuple):
    """One detected line as the filter takes it: its cubic z (c0..c3), what updates the filter y (z itself, or with
    `measure_at` the cubic's values there) with its noise R, and its existence probability."""

    z: np.ndarray
    r: np.ndarray
    prob: float
    y: np.ndarray


@dataclass
class LineMemory:
    """What the tracker remembers of one line beside its state: when it was last seen (s), its last existence
    probability, its consecutive outlier frames, whether its detector reported a variance, and its residual
    noise."""

    last_seen: float | None = None
    existence: float = 0.0
    outliers: int = 0
    reported: bool = False
    residual_var: float | None = None
    """Running mean of the squared c0 residual (with `measure_at`: at its first distance) after each update (m²), its
    first value at most measurement_std[0]² (range_std²): how far the line sits from the rest."""


class LaneTracker:
    """Tracks the ego lines across frames; `update(detection, speed, yaw_rate)` returns the tracked detection."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params if params is not None else TrackerParams()
        self.kf = KalmanFilter(dim_x=DIM, dim_z=N)
        ahead = np.asarray(self.params.measure_at, dtype=float)
        self._ahead = np.stack([ahead**0, ahead, ahead**2, ahead**3], axis=1) if len(ahead) else None
        """(k, 4): a cubic's coefficients to its values at the `measure_at` distances; None without them."""
        self._observe = tuple(_SELECT[side] if self._ahead is None else self._ahead @ _SELECT[side]
                              for side in (LEFT, RIGHT))
        """Per line, H: what a detection of it measures (its cubic, or the cubic's values ahead) from the state."""
        self.reset()

    def reset(self) -> None:
        """Forget every line."""
        self.started = False
        self.t: float | None = None
        self.odometry = (0.0, 0.0)
        self.lines = [LineMemory(), LineMemory()]
        self.x_range = (0.0, 0.0)
        self.swaps = 0
        """Line re-associations so far: + the car crossed its left line, − its right line."""

    # ---- model -----------------------------------------------------------------------------------------
    def _process_noise(self, dt: float, dx: float) -> np.ndarray:
        p = self.params
        q = p.lateral_std**2 * dt * np.outer(_COMMON_OFFSET, _COMMON_OFFSET)
        curvature_std = p.curvature_std if self._ahead is None else p.ahead_curvature_std
        q += np.diag([p.width_std**2 * dx, p.width_std**2 * dx, (p.yaw_rate_std * dt) ** 2,
                      curvature_std**2 * dx, p.curvature_rate_std**2 * dx])
        return q

    def _measurement(self, ld: LaneDetection, side: int) -> Measurement | None:
        """A detected line that may update the filter, else None."""
        coeffs, prob = (ld.left, ld.left_prob) if side == LEFT else (ld.right, ld.right_prob)
        var = ld.left_var if side == LEFT else ld.right_var
        if coeffs is None or not prob >= self.params.min_existence:
            return None
        z = np.zeros(N)
        c = np.asarray(coeffs, dtype=float)[:N]
        z[: len(c)] = c
        if not np.isfinite(z).all():
            return None
        p = self.params
        r = (np.asarray(p.measurement_std, dtype=float) ** 2 if self._ahead is None
             else np.full(len(p.measure_at), p.range_std**2))
        adapted = self.lines[side].residual_var
        if var is not None and math.isfinite(var) and var > 0:
            r = r * (var / p.measurement_std[0] ** 2)
        elif adapted is not None:
            r = r * (max(adapted, p.min_offset_std**2) / r[0])
        y = z if self._ahead is None else self._ahead @ z
        return Measurement(z, np.diag(r / min(prob, 1.0)), min(prob, 1.0), y)

    def _start(self, meas: list[Measurement | None]) -> None:
        p = self.params
        seen = [m for m in meas if m is not None]
        x = np.zeros(DIM)
        x[_SHARED] = np.mean([m.z[1:] for m in seen], axis=0)
        var = np.zeros(DIM)
        if self._ahead is None:
            var[_SHARED] = np.mean([np.diag(m.r)[1:] for m in seen], axis=0) / len(seen)
        else:  # the shared terms' first variance as the coefficients' nominal noise would give it
            shared = np.asarray(p.measurement_std[1:], dtype=float) ** 2
            var[_SHARED] = np.mean([shared / m.prob for m in seen], axis=0) / len(seen)
        for side in (LEFT, RIGHT):
            m = meas[side]
            if m is not None:
                x[side], var[side] = m.z[0], m.r[0, 0] if self._ahead is None else p.measurement_std[0] ** 2 / m.prob
            else:
                x[side] = seen[0].z[0] + (1.0 if side == LEFT else -1.0) * NOMINAL_LANE_WIDTH
                var[side] = p.unseen_std**2
        self.kf.x = x[:, None]
        self.kf.P = np.diag(var)
        self.started = True

    def _predict(self, dt: float, speed: float, yaw_rate: float) -> None:
        v0, r0 = self.odometry
        dx = 0.5 * (v0 + speed) * dt
        dpsi = 0.5 * (r0 + yaw_rate) * dt
        u = np.array([-dx * dpsi / 2.0, -dx * dpsi / 2.0, -dpsi, 0.0, 0.0])[:, None]
        self.kf.predict(u=u, B=np.eye(DIM), F=transition(dx), Q=self._process_noise(dt, abs(dx)))

    def _swap(self, direction: int) -> None:
        """Re-associate after the car crossed its left (+1) or right (−1) line."""
        t = _SWAP_LEFT if direction > 0 else _SWAP_RIGHT
        new = LEFT if direction > 0 else RIGHT  # the line one lane further, never seen
        kept = 1 - new
        self.kf.x = t @ self.kf.x
        self.kf.P = t @ self.kf.P @ t.T
        self.kf.P[new, new] += self.params.unseen_std**2
        self.lines[kept], self.lines[new] = self.lines[new], LineMemory()
        self.swaps += direction

    def _associate(self, meas: list[Measurement | None]) -> None:
        """Swap the lines when the car has crossed one: by the detections where there are any (the
        hypothesis whose offsets are nearest them, among the crossings of a line predicted within `cross_margin` of
        the car), else by the predicted offsets' signs."""
        x = self.kf.x[:, 0]
        if any(m is not None for m in meas):
            margin = self.params.cross_margin
            costs = {}
            for direction, t in ((0, _E), (1, _SWAP_LEFT), (-1, _SWAP_RIGHT)):
                if direction * x[LEFT if direction > 0 else RIGHT] > margin:
                    continue  # that line is too far off the car to have been crossed
                h = t @ x
                costs[direction] = sum(abs(m.z[0] - h[side]) for side, m in enumerate(meas) if m is not None)
            best = min(costs, key=costs.get)
        else:
            best = 1 if x[LEFT] < 0.0 else (-1 if x[RIGHT] > 0.0 else 0)
        if best:
            self._swap(best)

    def _gate(self, meas: list[Measurement | None]) -> list[Measurement | None]:
        """Outlier handling on the offsets: returns the measurements without the outliers, after opening the
        state's offset covariance where a jump is accepted as real."""
        p = self.params
        x, cov = self.kf.x[:, 0], self.kf.P
        nu, s = [0.0, 0.0], [1.0, 1.0]
        for side, m in enumerate(meas):
            if m is not None:
                row = self._gate_row(side)
                nu[side] = m.y[0] - (x[side] if row is None else row @ x)
                s[side] = (cov[side, side] if row is None else row @ cov @ row) + m.r[0, 0]
        z = [nu[k] / math.sqrt(s[k]) if meas[k] is not None else 0.0 for k in (LEFT, RIGHT)]
        out = [abs(v) > p.gate for v in z]
        both = meas[LEFT] is not None and meas[RIGHT] is not None
        if both and out[LEFT] and out[RIGHT]:
            rows = (self._gate_row(LEFT), self._gate_row(RIGHT))
            shared = cov[LEFT, RIGHT] if rows[LEFT] is None else rows[LEFT] @ cov @ rows[RIGHT]
            diff_var = s[LEFT] + s[RIGHT] - 2 * shared
            if abs(nu[LEFT] - nu[RIGHT]) <= p.gate * math.sqrt(max(diff_var, 1e-12)):
                if not self._heading_agrees(meas, (LEFT, RIGHT)):
                    return [None, None]  # both lines moved and turned at once: neither is the lane seen before
                self._open(_COMMON_OFFSET, 0.5 * (nu[LEFT] + nu[RIGHT]))  # the car moved: both lines jump
                for line in self.lines:
                    line.outliers = 0
                return meas
        gated = list(meas)
        for side, m in enumerate(meas):
            if m is None:
                continue
            line = self.lines[side]
            if not out[side]:
                line.outliers = 0
                continue
            line.outliers += 1
            other_agrees = meas[1 - side] is not None and not out[1 - side]
            needed = p.width_confirm_frames if other_agrees else p.confirm_frames
            if line.outliers >= needed and self._heading_agrees(meas, (side,)):
                self._open(_E[side] if other_agrees else _COMMON_OFFSET, nu[side])
                line.outliers = 0
            else:
                gated[side] = None
        return gated

    def _plausible(self, meas: list[Measurement | None], t: float) -> list[Measurement | None]:
        """The measurements without a line being taken up (not seen within `max_coast`) that would make the lane
        narrower or wider than `lane_width_range` against the other line as tracked, where that one was seen within
        `max_coast` (at each `measure_at` distance; at the car without them): a lane's lines are a lane's width apart,
        and a misread line, such as the first line read past a junction, seldom is. A line already tracked is left
        to the gate, so that a line dragged outwards cannot make the tracker drop the other."""
        x = self.kf.x[:, 0]
        kept = list(meas)
        for side, m in enumerate(meas):
            if m is None or self._seen(side, t) or not self._seen(1 - side, t):
                continue
            values = self._values(m)
            tracked = (self._observe[1 - side] @ x)[: len(values)]
            if not self._a_lane_wide(values - tracked if side == LEFT else tracked - values):
                kept[side] = None
        return kept

    def _startable(self, meas: list[Measurement | None]) -> bool:
        """Whether the measurements may start a track: a line seen alone, or two lines a lane's width apart
        (`lane_width_range`, as `_plausible` judges); two that are not start nothing, since which of them is misread
        cannot be told (a pair read off a junction's other paint, or one line read a lane further, seldom is a lane)."""
        if meas[LEFT] is None or meas[RIGHT] is None:
            return meas[LEFT] is not None or meas[RIGHT] is not None
        return self._a_lane_wide(self._values(meas[LEFT]) - self._values(meas[RIGHT]))

    def _values(self, m: Measurement) -> np.ndarray:
        """A detected line's values at the `measure_at` distances (its offset at the car without them)."""
        return m.y if self._ahead is not None else m.y[:1]

    def _a_lane_wide(self, width: np.ndarray) -> bool:
        """Whether a lane's width at each distance is within `lane_width_range`."""
        low, high = self.params.lane_width_range
        return bool(np.all((width >= low) & (width <= high)))

    def _seen(self, side: int, t: float) -> bool:
        """Whether the line was seen within `max_coast` before `t`."""
        last = self.lines[side].last_seen
        return last is not None and t - last <= self.params.max_coast

    def _gate_row(self, side: int) -> np.ndarray | None:
        """The state's row giving the line's value at the first `measure_at` distance (None: its offset c0)."""
        return None if self._ahead is None else self._observe[side][0]

    def _heading_agrees(self, meas: list[Measurement | None], sides: tuple[int, ...]) -> bool:
        """Whether the mean heading c1 of these detected lines is within `gate` of the tracked heading, with
        each line's c1 noise `measurement_std[1]`² over its existence probability: a lateral jump of the car
        leaves its heading to the lane as the gyro carried it, a line read off the wrong paint rarely does."""
        p = self.params
        z = np.mean([meas[side].z[1] for side in sides])
        r = sum(p.measurement_std[1] ** 2 / meas[side].prob for side in sides) / len(sides) ** 2
        return abs(z - self.kf.x[2, 0]) <= p.gate * math.sqrt(self.kf.P[2, 2] + r)

    def _open(self, direction: np.ndarray, jump: float) -> None:
        """Add variance along `direction` of the state so the next update takes a jump of this size."""
        self.kf.P = self.kf.P + (jump**2 + 1.0) * 100.0 * np.outer(direction, direction)

    def _update(self, meas: list[Measurement | None]) -> None:
        rows = [side for side in (LEFT, RIGHT) if meas[side] is not None]
        if not rows:
            return
        z = np.concatenate([meas[side].y for side in rows])[:, None]
        h = np.vstack([self._observe[side] for side in rows])
        k_rows = len(self._observe[LEFT])
        r = np.zeros((len(z), len(z)))
        for k, side in enumerate(rows):
            r[k * k_rows : (k + 1) * k_rows, k * k_rows : (k + 1) * k_rows] = meas[side].r
        self.kf.update(z, R=r, H=h)
        a = self.params.adapt_rate
        for side in rows:
            line = self.lines[side]
            row = self._gate_row(side)
            if row is None:
                spread = (meas[side].z[0] - self.kf.x[side, 0]) ** 2 + self.kf.P[side, side]
            else:
                spread = (meas[side].y[0] - row @ self.kf.x[:, 0]) ** 2 + row @ self.kf.P @ row
            if line.residual_var is None:  # one frame cannot say the line is noisier than the nominal model
                nominal = self.params.measurement_std[0] if row is None else self.params.range_std
                line.residual_var = min(spread, nominal**2)
            else:
                line.residual_var = (1 - a) * line.residual_var + a * spread

    # ---- interface -------------------------------------------------------------------------------------
    def update(self, ld: LaneDetection, speed: float, yaw_rate: float) -> LaneDetection:
        """Predict to `ld.timestamp` with the odometry (speed m/s, yaw rate rad/s, now), update with `ld`, and
        return the tracked lines (a line last seen more than `max_coast` s ago is None, probability 0; a
        detection the gate leaves out does not count as seen)."""
        meas = [self._measurement(ld, side) for side in (LEFT, RIGHT)]
        if self.started and (self._seen(LEFT, ld.timestamp) or self._seen(RIGHT, ld.timestamp)):
            self._predict(max(0.0, ld.timestamp - self.t), speed, yaw_rate)
            self._associate(meas)
            meas = self._gate(self._plausible(meas, ld.timestamp))
            self._update(meas)
        elif self._startable(meas):
            self.reset()
            self._start(meas)
        else:
            meas = [None, None]
        self.t, self.odometry = ld.timestamp, (speed, yaw_rate)
        for side in (LEFT, RIGHT):
            if meas[side] is not None:
                line = self.lines[side]
                line.last_seen = ld.timestamp
                line.existence = ld.left_prob if side == LEFT else ld.right_prob
                line.reported = (ld.left_var if side == LEFT else ld.right_var) is not None
        if meas[LEFT] is not None or meas[RIGHT] is not None:
            self.x_range = ld.x_range
        return self._output(ld.timestamp)

    def _output(self, t: float) -> LaneDetection:
        lines: list[np.ndarray | None] = [None, None]
        probs = [0.0, 0.0]
        var: list[float | None] = [None, None]
        for side in (LEFT, RIGHT):
            line = self.lines[side]
            if self.started and self._seen(side, t):
                lines[side] = _SELECT[side] @ self.kf.x[:, 0]
                probs[side] = float(line.existence)
                var[side] = float(self.kf.P[side, side]) if line.reported else None
        return LaneDetection(t, lines[LEFT], lines[RIGHT], probs[LEFT], probs[RIGHT], self.x_range,
                             var[LEFT], var[RIGHT])
