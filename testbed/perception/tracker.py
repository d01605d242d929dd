"""Lane tracker: a Kalman filter over both ego lines' cubics, predicted with the car's own odometry.

State: the left and right lines' coefficients (c0, c1, c2, c3) in the vehicle frame, i.e. each line's
offset, heading, half curvature and a sixth of the curvature rate. Between frames the car advances
dx = v·dt and turns dψ = r·dt (wheel speed and yaw rate from the chassis, trapezoid over the interval; never
GNSS or the MSF), so each line becomes y'(x) = y(x + dx) − dψ·x − dx·dψ/2: the lateral motion relative to the
lane comes from the tracked heading, not from smoothing toward the past. Process noise: ego motion the
odometry misses (lateral slip, yaw-rate error) and the road's curvature changes are common to both lines,
lane-width changes are per line; the common part correlates the lines, so one seen line carries the other.
Each present detected line updates the filter with noise `measurement_std` (c0's variance replaced by the
detector's `left_var` / `right_var` when reported) divided by its existence probability. A line whose
offset innovation exceeds `gate` standard deviations is left out; both lines jumping together is the
car moving (accepted at once), one line off for `confirm_frames` frames in a row is a real change
(accepted then). Lines are re-associated when the car crosses one (left becomes right, and the next line
over is predicted one lane width further). A line not seen for `max_coast` seconds is no longer output;
an output line carries its last detected existence probability, and the filter's c0 variance where the
detector reports its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from testbed.lane_detection import LaneDetection

LEFT, RIGHT = 0, 1
N = 4  # coefficients per line
NOMINAL_LANE_WIDTH = 3.5  # m: where an unseen line is first placed, with `unseen_std` around it
_C0 = (0, N)  # state indices of the lines' offsets


@dataclass(frozen=True)
class TrackerParams:
    """Noise model and gating of `LaneTracker` (SI units; process noises per √s or per √m travelled)."""

    measurement_std: tuple[float, float, float, float] = (0.10, 0.02, 1e-3, 3e-5)
    """Std of a detected line's c0..c3 at existence probability 1 (c0 replaced by the reported variance)."""
    lateral_std: float = 0.10
    """m/√s: lateral motion of the car the odometry does not see (slip), common to both lines."""
    yaw_rate_std: float = 0.01
    """rad/s: yaw-rate error, common to both lines' heading."""
    curvature_std: float = 1e-4
    """1/m per √m: random walk of c2 (road curvature changes), common to both lines."""
    curvature_rate_std: float = 1e-5
    """1/m² per √m: random walk of c3, common to both lines."""
    width_std: float = 0.01
    """m per √m: random walk of each line's own offset (lane width changes)."""
    unseen_std: float = 1.0
    """m: c0 std of a line placed from the other one, never seen yet."""
    gate: float = 3.5
    """Offset innovations beyond this many standard deviations are outliers."""
    confirm_frames: int = 2
    """Consecutive outlier frames after which a line's jump is taken as real."""
    max_coast: float = 1.0
    """s a line is output after it was last seen."""
    min_existence: float = 0.05
    """A detected line with a lower existence probability does not update the filter."""

    def __post_init__(self) -> None:
        checks = [
            (len(self.measurement_std) == N and all(s > 0 for s in self.measurement_std),
             "measurement_std needs 4 positive values (c0..c3)"),
            (min(self.lateral_std, self.yaw_rate_std, self.curvature_std, self.curvature_rate_std,
                 self.width_std) >= 0, "process noise stds must be >= 0"),
            (self.unseen_std > 0 and self.gate > 0, "unseen_std and gate must be > 0"),
            (self.confirm_frames >= 1, "confirm_frames must be >= 1"),
            (self.max_coast >= 0, "max_coast must be >= 0 s"),
            (0.0 <= self.min_existence < 1.0, "min_existence must be in [0, 1)"),
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


def _both(v: np.ndarray) -> np.ndarray:
    """A per-line (4,) direction applied to both lines: (8,)."""
    return np.concatenate([v, v])


def _line(side: int, v: np.ndarray) -> np.ndarray:
    out = np.zeros(2 * N)
    out[side * N : (side + 1) * N] = v
    return out


_E = np.eye(N)
_SELECT = [np.eye(2 * N)[side * N : (side + 1) * N] for side in (LEFT, RIGHT)]
_SWAP_LEFT = np.block([[2 * _E, -_E], [_E, np.zeros((N, N))]])
"""The car crossed its left line: the new right line is the old left, the new left one lane width further."""
_SWAP_RIGHT = np.block([[np.zeros((N, N)), _E], [-_E, 2 * _E]])
"""The car crossed its right line."""


@dataclass
class LineMemory:
    """What the tracker remembers of one line beside its state: when it was last seen (s), its last existence
    probability, its consecutive outlier frames, and whether its detector reported a variance."""

    last_seen: float | None = None
    existence: float = 0.0
    outliers: int = 0
    reported: bool = False


class LaneTracker:
    """Tracks the ego lines across frames; `update(detection, speed, yaw_rate)` returns the tracked detection."""

    def __init__(self, params: TrackerParams | None = None) -> None:
        self.params = params if params is not None else TrackerParams()
        self.kf = KalmanFilter(dim_x=2 * N, dim_z=N)
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
        q = np.zeros((2 * N, 2 * N))
        for var, unit in ((p.lateral_std**2 * dt, 0), ((p.yaw_rate_std * dt) ** 2, 1),
                          (p.curvature_std**2 * dx, 2), (p.curvature_rate_std**2 * dx, 3)):
            g = _both(_E[unit])
            q += var * np.outer(g, g)
        for side in (LEFT, RIGHT):
            g = _line(side, _E[0])
            q += p.width_std**2 * dx * np.outer(g, g)
        return q

    def _measurement(self, ld: LaneDetection, side: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(z, R) of a detected line that may update the filter, else None."""
        coeffs, prob = (ld.left, ld.left_prob) if side == LEFT else (ld.right, ld.right_prob)
        var = ld.left_var if side == LEFT else ld.right_var
        if coeffs is None or not prob >= self.params.min_existence:
            return None
        z = np.zeros(N)
        c = np.asarray(coeffs, dtype=float)[:N]
        z[: len(c)] = c
        if not np.isfinite(z).all():
            return None
        std = np.asarray(self.params.measurement_std, dtype=float)
        r = std**2
        if var is not None and math.isfinite(var) and var > 0:
            r = r * (var / r[0])
        return z, np.diag(r / min(prob, 1.0))

    def _start(self, meas: list[tuple[np.ndarray, np.ndarray] | None]) -> None:
        p = self.params
        seen = [m for m in meas if m is not None]
        x = np.zeros(2 * N)
        big = np.diag(np.asarray(p.measurement_std) ** 2 * 100.0)
        blocks = [big.copy(), big.copy()]
        for side in (LEFT, RIGHT):
            m = meas[side]
            if m is not None:
                x[side * N : (side + 1) * N] = m[0]
                blocks[side] = m[1].copy()
            else:
                other = seen[0][0]
                sign = 1.0 if side == LEFT else -1.0
                x[side * N : (side + 1) * N] = other + sign * NOMINAL_LANE_WIDTH * _E[0]
                blocks[side][0, 0] = p.unseen_std**2
        self.kf.x = x[:, None]
        self.kf.P = np.block([[blocks[0], np.zeros((N, N))], [np.zeros((N, N)), blocks[1]]])
        self.started = True

    def _predict(self, dt: float, speed: float, yaw_rate: float) -> None:
        v0, r0 = self.odometry
        dx = 0.5 * (v0 + speed) * dt
        dpsi = 0.5 * (r0 + yaw_rate) * dt
        f = np.kron(np.eye(2), shift_matrix(dx))
        u = _both(np.array([-dx * dpsi / 2.0, -dpsi, 0.0, 0.0]))[:, None]
        self.kf.predict(u=u, B=np.eye(2 * N), F=f, Q=self._process_noise(dt, abs(dx)))

    def _offset(self, side: int) -> float:
        return float(self.kf.x[side * N, 0])

    def _swap(self, direction: int) -> None:
        """Re-associate after the car crossed its left (+1) or right (−1) line."""
        t = _SWAP_LEFT if direction > 0 else _SWAP_RIGHT
        new = LEFT if direction > 0 else RIGHT  # the line one lane further, never seen
        kept = 1 - new
        self.kf.x = t @ self.kf.x
        self.kf.P = t @ self.kf.P @ t.T
        self.kf.P[new * N, new * N] += self.params.unseen_std**2
        self.lines[kept], self.lines[new] = self.lines[new], LineMemory()
        self.swaps += direction

    def _associate(self, meas: list[tuple[np.ndarray, np.ndarray] | None]) -> None:
        """Swap the lines when the car has crossed one: by the detections where there are any (the
        hypothesis whose offsets are nearest them), else by the predicted offsets' signs."""
        x = self.kf.x[:, 0]
        if any(m is not None for m in meas):
            costs = {}
            for direction, t in ((0, np.eye(2 * N)), (1, _SWAP_LEFT), (-1, _SWAP_RIGHT)):
                h = t @ x
                costs[direction] = sum(abs(m[0][0] - h[side * N]) for side, m in enumerate(meas) if m is not None)
            best = min(costs, key=costs.get)
        else:
            best = 1 if x[_C0[LEFT]] < 0.0 else (-1 if x[_C0[RIGHT]] > 0.0 else 0)
        if best:
            self._swap(best)

    def _gate(self, meas: list[tuple[np.ndarray, np.ndarray] | None]) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """Outlier handling on the offsets: returns the measurements without the outliers, after opening the
        state's offset covariance where a jump is accepted as real."""
        p = self.params
        x, cov = self.kf.x[:, 0], self.kf.P
        nu, s = [0.0, 0.0], [1.0, 1.0]
        for side, m in enumerate(meas):
            if m is not None:
                i = side * N
                nu[side] = m[0][0] - x[i]
                s[side] = cov[i, i] + m[1][0, 0]
        z = [nu[k] / math.sqrt(s[k]) if meas[k] is not None else 0.0 for k in (LEFT, RIGHT)]
        out = [abs(v) > p.gate for v in z]
        both = meas[LEFT] is not None and meas[RIGHT] is not None
        if both and out[LEFT] and out[RIGHT]:
            diff_var = s[LEFT] + s[RIGHT] - 2 * cov[_C0[LEFT], _C0[RIGHT]]
            if abs(nu[LEFT] - nu[RIGHT]) <= p.gate * math.sqrt(max(diff_var, 1e-12)):
                self._open(_both(_E[0]), 0.5 * (nu[LEFT] + nu[RIGHT]))  # the car moved: both lines jump
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
            if line.outliers >= p.confirm_frames:
                other_agrees = meas[1 - side] is not None and not out[1 - side]
                self._open(_line(side, _E[0]) if other_agrees else _both(_E[0]), nu[side])
                line.outliers = 0
            else:
                gated[side] = None
        return gated

    def _open(self, direction: np.ndarray, jump: float) -> None:
        """Add variance along `direction` of the state so the next update takes a jump of this size."""
        self.kf.P = self.kf.P + (jump**2 + 1.0) * 100.0 * np.outer(direction, direction)

    def _update(self, meas: list[tuple[np.ndarray, np.ndarray] | None]) -> None:
        rows = [side for side in (LEFT, RIGHT) if meas[side] is not None]
        if not rows:
            return
        z = np.concatenate([meas[side][0] for side in rows])[:, None]
        h = np.vstack([_SELECT[side] for side in rows])
        r = np.zeros((len(z), len(z)))
        for k, side in enumerate(rows):
            r[k * N : (k + 1) * N, k * N : (k + 1) * N] = meas[side][1]
        self.kf.update(z, R=r, H=h)

    # ---- interface -------------------------------------------------------------------------------------
    def update(self, ld: LaneDetection, speed: float, yaw_rate: float) -> LaneDetection:
        """Predict to `ld.timestamp` with the odometry (speed m/s, yaw rate rad/s, now), update with `ld`, and
        return the tracked lines (a line last seen more than `max_coast` s ago is None, probability 0)."""
        p = self.params
        meas = [self._measurement(ld, side) for side in (LEFT, RIGHT)]
        if self.started and any(line.last_seen is not None and ld.timestamp - line.last_seen <= p.max_coast
                                for line in self.lines):
            self._predict(max(0.0, ld.timestamp - self.t), speed, yaw_rate)
            self._associate(meas)
            self._update(self._gate(meas))
        elif any(m is not None for m in meas):
            self.reset()
            self._start(meas)
        self.t, self.odometry = ld.timestamp, (speed, yaw_rate)
        for side in (LEFT, RIGHT):
            if meas[side] is not None:
                self.lines[side] = LineMemory(ld.timestamp, ld.left_prob if side == LEFT else ld.right_prob,
                                              self.lines[side].outliers,
                                              (ld.left_var if side == LEFT else ld.right_var) is not None)
        if meas[LEFT] is not None or meas[RIGHT] is not None:
            self.x_range = ld.x_range
        return self._output(ld.timestamp)

    def _output(self, t: float) -> LaneDetection:
        lines: list[np.ndarray | None] = [None, None]
        probs = [0.0, 0.0]
        var: list[float | None] = [None, None]
        for side in (LEFT, RIGHT):
            line = self.lines[side]
            if self.started and line.last_seen is not None and t - line.last_seen <= self.params.max_coast:
                lines[side] = self.kf.x[side * N : (side + 1) * N, 0].copy()
                probs[side] = float(line.existence)
                var[side] = float(self.kf.P[side * N, side * N]) if line.reported else None
        return LaneDetection(t, lines[LEFT], lines[RIGHT], probs[LEFT], probs[RIGHT], self.x_range,
                             var[LEFT], var[RIGHT])
