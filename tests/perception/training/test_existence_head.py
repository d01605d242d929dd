"""The existence refit: frames without lane lines drawn from a seed, the refit moving only the existence outputs
(the lines decode exactly as before) and rejecting the negatives it was fitted on while keeping painted roads."""

from __future__ import annotations

import numpy as np
import torch

from testbed.perception.detectors.neural import FRAME_SHAPE, X_ANCHORS, load_model, preprocess
from testbed.perception.training.existence_head import hidden_features, negative_frames, refit_existence
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

RIG = CameraRig(get_vehicle("sedan").camera)


def _road(left: float, right: float, grey: int) -> np.ndarray:
    """The rig's view of a flat road with 15 cm white lines at `left` and `right` (m) under a plain sky."""
    v, u = np.mgrid[0 : RIG.height, 0 : RIG.width].astype(np.float64)
    ground = RIG.pixel_to_ground(np.column_stack([u.ravel(), v.ravel()]))
    out = np.tile(np.array([[150, 190, 230]], np.uint8), (len(ground), 1))
    ok = np.isfinite(ground).all(axis=1)
    out[ok] = grey
    for y in (left, right):
        out[ok & (np.abs(ground[:, 1] - y) < 0.075)] = 235
    return out.reshape(RIG.height, RIG.width, 3)


def test_negatives_are_drawn_from_their_seed():
    a, b = negative_frames(10, seed=3), negative_frames(10, seed=3)
    assert all(x.shape == (*FRAME_SHAPE, 3) and x.dtype == np.uint8 for x in a)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], negative_frames(10, seed=4)[0])


def test_the_refit_rejects_negatives_keeps_roads_and_leaves_the_lines_alone():
    torch.manual_seed(0)
    model = load_model()
    rng = np.random.default_rng(0)
    roads = [_road(rng.uniform(1.3, 2.1), -rng.uniform(1.3, 2.1), int(rng.integers(60, 120))) for _ in range(40)]
    negatives = negative_frames(60, seed=0)
    w, b = refit_existence(model, hidden_features(model, roads), torch.ones(40, 2), hidden_features(model,
                                                                                                    negatives))
    held_out = hidden_features(model, negative_frames(30, seed=1))
    assert ((held_out @ w.T + b) < 0).all(dim=1).float().mean() >= 0.9
    assert ((hidden_features(model, roads) @ w.T + b) > 0).all()
    refitted = load_model()
    rows = slice(2 * len(X_ANCHORS), 2 * len(X_ANCHORS) + 2)
    with torch.no_grad():
        refitted.glob[3].weight[rows], refitted.glob[3].bias[rows] = w, b
        x = torch.from_numpy(np.stack([preprocess(f) for f in roads[:4] + negatives[:4]]))
        cols0, exist0 = model(x)
        cols1, exist1 = refitted(x)
    assert torch.equal(cols0, cols1) and not torch.equal(exist0, exist1)
