"""Classical lane detector (OpenCV): inverse perspective mapping, adaptive ridge threshold, sliding windows.

The frame is warped to a bird's-eye grid over the ground (x in [X_NEAR, X_FAR] m ahead, |y| <= Y_HALF m)
with the rig's flat-ground homography. Paint is a bright ridge: the (R+G)/2 channel minus its 1 m wide
horizontal box mean, thresholded at a multiple of its robust spread (so the threshold follows exposure).
Left and right lines start at the column-histogram peaks nearest the car either side (weak peaks
ignored) and are traced by sliding windows; the pixels found are fitted with np.polyfit (quadratic,
stored as a cubic with c3 = 0).
Existence probability is the fraction of windows that found paint.
"""

from __future__ import annotations

import cv2
import numpy as np

from testbed.perception.detection import CameraFrame, LaneDetection, LaneDetector
from vehicles.camera_rig import CameraRig

X_NEAR, X_FAR, Y_HALF = 5.0, 30.0, 6.0  # m: bird's-eye extent
RES_X, RES_Y = 0.2, 0.04  # m per bird's-eye pixel (rows along x, columns along y)
N_WINDOWS = 10
WINDOW_HALF = 0.5  # m: lateral half width of a search window
MIN_PIXELS = 4


def nearest_peak(hist: np.ndarray, share: float = 0.4) -> int:
    """Index of the first local maximum holding at least `share` of the strongest column count."""
    smooth = np.convolve(hist, np.ones(5), mode="same")
    top = smooth.max()
    if top <= 0:
        return int(np.argmax(smooth))
    for i in range(len(smooth)):
        left = smooth[i - 1] if i > 0 else -1.0
        right = smooth[i + 1] if i + 1 < len(smooth) else -1.0
        if smooth[i] >= share * top and smooth[i] >= left and smooth[i] >= right:
            return i
    return int(np.argmax(smooth))


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
        self.box = max(3, round(1.0 / RES_Y) | 1)

    def birdseye(self, image: np.ndarray) -> np.ndarray:
        """(R+G)/2 intensity resampled onto the bird's-eye grid (float32)."""
        rg = 0.5 * (image[:, :, 0].astype(np.float32) + image[:, :, 1].astype(np.float32))
        return cv2.warpPerspective(rg, self.pixel_from_bev, (self.cols, self.rows),
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                   borderMode=cv2.BORDER_REPLICATE)

    def paint_mask(self, bev: np.ndarray) -> np.ndarray:
        ridge = bev - cv2.blur(bev, (self.box, 1))
        spread = 1.4826 * float(np.median(np.abs(ridge - np.median(ridge)))) + 0.5
        return ridge > self.ridge_k * spread

    def _trace(self, mask: np.ndarray, col: int) -> tuple[np.ndarray | None, float]:
        half = round(WINDOW_HALF / RES_Y)
        win_rows = self.rows // N_WINDOWS
        xs, ys, hits = [], [], 0
        for w in range(N_WINDOWS):
            r1 = self.rows - w * win_rows
            r0 = r1 - win_rows
            c0, c1 = max(0, col - half), min(self.cols, col + half)
            rr, cc = np.nonzero(mask[r0:r1, c0:c1])
            if len(rr) >= MIN_PIXELS:
                hits += 1
                xs.append(self.x_of_row[rr + r0])
                ys.append(Y_HALF - (cc + c0) * RES_Y)
                col = round(float(np.mean(cc))) + c0
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
        hist = mask[self.rows // 2 :].sum(axis=0)
        centre = self.cols // 2
        lo, hi = round(0.4 / RES_Y), round(3.8 / RES_Y)
        left_col = centre - lo - nearest_peak(hist[centre - hi : centre - lo][::-1])
        right_col = centre + lo + nearest_peak(hist[centre + lo : centre + hi])
        left, lp = self._trace(mask, left_col)
        right, rp = self._trace(mask, right_col)
        return LaneDetection(frame.t, left, right, lp if left is not None else 0.0,
                             rp if right is not None else 0.0, (0.0, X_FAR))
