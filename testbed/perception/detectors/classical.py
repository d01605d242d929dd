"""Classical lane detector (OpenCV): inverse perspective mapping, adaptive ridge threshold, sliding windows.

The frame is warped to a bird's-eye grid over the ground (x in [X_NEAR, X_FAR] m ahead, |y| <= Y_HALF m)
with the rig's flat-ground homography. Paint is a bright ridge: the (R+G)/2 channel minus the brighter of
the road means SIDE_OFFSET to its left and right, thresholded at a multiple of its robust spread (so the
threshold follows exposure).
The start search shears the near half of the paint mask by each candidate heading (±HEADING_MAX) and
keeps the sharpest lateral histogram (lines are parallel, so one heading straightens them all); its
peaks are candidate lines at X_NEAR. The ego pair is the narrowest pair of peaks a plausible lane width
apart that straddles the car; with no such pair, the innermost peak each side within a lane width.
Each start is traced by sliding windows that follow the heading; the pixels found are fitted with
np.polyfit (quadratic, stored as a cubic with c3 = 0).
Existence probability is the fraction of windows that found paint.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbed.lane_detection import CameraFrame, LaneDetection, LaneDetector
from vehicles.camera_rig import CameraRig

X_NEAR, X_FAR, Y_HALF = 5.0, 30.0, 6.0  # m: bird's-eye extent
RES_X, RES_Y = 0.2, 0.04  # m per bird's-eye pixel (rows along x, columns along y)
SIDE_WIDTH, SIDE_OFFSET = 0.4, 0.35  # m: road samples either side of a paint candidate (width, centre offset)
N_WINDOWS = 10
WINDOW_HALF = 0.5  # m: lateral half width of a search window
MIN_PIXELS = 4
HEADING_MAX, HEADING_STEP = np.radians(7.0), np.radians(0.5)  # start search over the heading to the lines
LANE_WIDTH_RANGE = (2.6, 4.4)  # m: plausible ego lane widths for the start pair
PEAK_SHARE = 0.25  # a histogram peak must hold this share of the strongest one
MIN_PEAK_ROWS = 8  # and paint in this many bird's-eye rows


def histogram_peaks(hist: np.ndarray, min_count: float) -> np.ndarray:
    """Indices of the local maxima of the (5-bin smoothed) histogram at least `min_count` high."""
    smooth = np.convolve(hist, np.ones(5) / 5.0, mode="same")
    floor = max(min_count, PEAK_SHARE * float(smooth.max()))
    inner = smooth[1:-1]
    peak = (inner >= smooth[:-2]) & (inner > smooth[2:]) & (inner >= floor)
    return np.flatnonzero(peak) + 1


def ego_pair(ys: np.ndarray) -> tuple[float | None, float | None]:
    """Lateral offsets (m) of the ego left and right lines among candidate lines `ys` (m, + left): the
    narrowest plausible pair straddling the car (curbs and verges lie outside the painted lines), else the
    innermost candidate each side within a lane width."""
    best, best_width = (None, None), np.inf
    for yl in ys[ys >= 0.0]:
        for yr in ys[ys < 0.0]:
            width = yl - yr
            if LANE_WIDTH_RANGE[0] <= width <= LANE_WIDTH_RANGE[1] and width < best_width:
                best, best_width = (float(yl), float(yr)), width
    if best[0] is not None:
        return best
    reach = LANE_WIDTH_RANGE[1] - 0.4
    left, right = ys[(ys >= 0.0) & (ys <= reach)], ys[(ys < 0.0) & (ys >= -reach)]
    return (float(left.min()) if len(left) else None, float(right.max()) if len(right) else None)


class ClassicalLaneDetector(LaneDetector):
    """IPM + sliding-window lane detector for one camera rig."""

    def __init__(self, rig: CameraRig, ridge_k: float = 3.5) -> None:
        self.rig = rig
        self.ridge_k = ridge_k
        self.rows = round((X_FAR - X_NEAR) / RES_X)
        self.cols = round(2 * Y_HALF / RES_Y)
        # bird's-eye pixel (c, r) -> ground (x, y): x = X_FAR - r RES_X, y = Y_HALF - c RES_Y
        ground_from_bev = np.array([[0.0, -RES_X, X_FAR], [-RES_Y, 0.0, Y_HALF], [0.0, 0.0, 1.0]])
        self.pixel_from_bev = rig.H @ ground_from_bev
        self.x_of_row = X_FAR - np.arange(self.rows) * RES_X
        self.box = max(3, round(SIDE_WIDTH / RES_Y) | 1)
        self.shift = round(SIDE_OFFSET / RES_Y)

    def birdseye(self, image: np.ndarray) -> np.ndarray:
        """(R+G)/2 intensity resampled onto the bird's-eye grid (float32)."""
        rg = 0.5 * (image[:, :, 0].astype(np.float32) + image[:, :, 1].astype(np.float32))
        return cv2.warpPerspective(rg, self.pixel_from_bev, (self.cols, self.rows),
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                   borderMode=cv2.BORDER_REPLICATE)

    def paint_mask(self, bev: np.ndarray) -> np.ndarray:
        """Pixels brighter than the road on *both* sides (a curb or a bright verge has road on one side only)."""
        side = np.pad(cv2.blur(bev, (self.box, 1)), ((0, 0), (self.shift, self.shift)), mode="edge")
        ridge = bev - np.maximum(side[:, : -2 * self.shift], side[:, 2 * self.shift :])
        spread = 1.4826 * float(np.median(np.abs(ridge - np.median(ridge)))) + 0.5
        return ridge > self.ridge_k * spread

    def start_search(self, mask: np.ndarray) -> tuple[float | None, float | None, float]:
        """Ego left and right line offsets (m) at X_NEAR and the heading slope dy/dx of the lines."""
        near = mask[self.rows // 2 :]
        rr, cc = np.nonzero(near)
        if len(rr) < MIN_PEAK_ROWS:
            return None, None, 0.0
        x = self.x_of_row[rr + self.rows // 2] - X_NEAR
        y = Y_HALF - cc * RES_Y
        best, best_sharp = None, -1.0
        for slope in np.tan(np.arange(-HEADING_MAX, HEADING_MAX + 1e-9, HEADING_STEP)):
            bins = np.round((Y_HALF - (y - slope * x)) / RES_Y).astype(int)
            ok = (bins >= 0) & (bins < self.cols)
            hist = np.bincount(bins[ok], minlength=self.cols).astype(float)
            sharp = float((hist**2).sum())
            if sharp > best_sharp:
                best, best_sharp = (hist, slope), sharp
        hist, slope = best
        left, right = ego_pair(Y_HALF - histogram_peaks(hist, MIN_PEAK_ROWS) * RES_Y)
        return left, right, float(slope)

    def _trace(self, mask: np.ndarray, y0: float, slope: float) -> tuple[np.ndarray | None, float]:
        half = round(WINDOW_HALF / RES_Y)
        win_rows = self.rows // N_WINDOWS
        xs, ys, hits = [], [], 0
        y_expect = y0
        for w in range(N_WINDOWS):
            r1 = self.rows - w * win_rows
            r0 = r1 - win_rows
            col = round((Y_HALF - y_expect) / RES_Y)
            c0, c1 = max(0, col - half), min(self.cols, col + half)
            rr, cc = np.nonzero(mask[r0:r1, c0:c1])
            if len(rr) >= MIN_PIXELS:
                hits += 1
                xs.append(self.x_of_row[rr + r0])
                ys.append(Y_HALF - (cc + c0) * RES_Y)
                y_expect = float(np.mean(ys[-1]))
            y_expect += slope * win_rows * RES_X
        prob = hits / N_WINDOWS
        if hits < 3:
            return None, prob
        x, y = np.concatenate(xs), np.concatenate(ys)
        quad = np.polyfit(x, y, 2)
        return np.array([quad[2], quad[1], quad[0], 0.0]), prob

    def detect(self, frame: CameraFrame) -> LaneDetection:
        img = frame.image
        if not (isinstance(img, np.ndarray) and img.shape == (self.rig.height, self.rig.width, 3)):
            return LaneDetection.empty(frame.t)
        if img.dtype != np.uint8:
            if not np.isfinite(img).all():
                return LaneDetection.empty(frame.t)
            img = np.clip(img, 0, 255).astype(np.uint8)
        mask = self.paint_mask(self.birdseye(img))
        y_left, y_right, slope = self.start_search(mask)
        left, lp = self._trace(mask, y_left, slope) if y_left is not None else (None, 0.0)
        right, rp = self._trace(mask, y_right, slope) if y_right is not None else (None, 0.0)
        return LaneDetection(frame.t, left, right, lp if left is not None else 0.0,
                             rp if right is not None else 0.0, (0.0, X_FAR))
