import math
from importlib import resources

import numpy as np
import pytest
import torch

from testbed.defense.ld_deviation import LdDeviation
from testbed.errors import UserError
from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.neural import (
    ANCHOR_WEIGHTS,
    DEFAULT_FIT,
    DEFAULT_WEIGHTS,
    FITS,
    GEOMETRY,
    MATRIX_FITS,
    X_ANCHORS,
    FrozenLaneNet,
    LaneNet,
    NeuralLaneDetector,
    anchor_variance,
    decode,
    fit_cubics,
    fit_matrices,
    lines_from_outputs,
    spread_cubics,
)

WEIGHTS_SHIPPED = (resources.files("testbed.perception.detectors") / "weights" / DEFAULT_WEIGHTS).is_file()
needs_weights = pytest.mark.skipif(
    not WEIGHTS_SHIPPED, reason="no trained weights ship (testbed/perception/detectors/weights/)")


@pytest.fixture(scope="module")
def detector() -> NeuralLaneDetector:
    return NeuralLaneDetector(threads=1)


@needs_weights
def test_shipped_weights_are_small_and_packaged():
    ref = resources.files("testbed.perception.detectors") / "weights" / "lanenet.pt"
    assert ref.is_file()
    assert len(ref.read_bytes()) <= 5 * 1024 * 1024


@pytest.mark.parametrize("coeffs", [[1.2, -0.05, 0.0, 0.0], [-1.7, 0.03, 1 / 120, 0.0], [1.75, 0.02, -1 / 200, 0.0]])
def test_anchor_fit_recovers_arcs_and_their_offset(coeffs):
    """Straight lines and circular arcs (c3 = 0) come back exactly, also from the far anchors alone."""
    y = torch.tensor(np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs))
    for present in (np.ones(len(X_ANCHORS)), np.r_[np.zeros(4), np.ones(len(X_ANCHORS) - 4)]):
        fitted = fit_cubics(y, torch.tensor(present)).numpy()
        for got, want, tol in zip(fitted[:3], coeffs[:3], (2e-3, 2e-4, 2e-5), strict=True):
            assert got == pytest.approx(want, abs=tol)


def test_anchor_fit_from_three_near_anchors_is_well_posed():
    near = torch.tensor([1.0] * 3 + [0.0] * (len(X_ANCHORS) - 3), dtype=torch.float64)
    line = torch.tensor(-1.8 + 0.03 * np.asarray(X_ANCHORS))
    fitted = fit_cubics(line, near).numpy()
    assert fitted[0] == pytest.approx(-1.8, abs=0.01) and fitted[1] == pytest.approx(0.03, abs=3e-3)


def test_column_expectation_decodes_to_metres():
    """A one-hot column at the pixel where y = 1.0 m projects decodes back to about 1.0 m."""
    u = GEOMETRY.y_to_u(np.full(len(X_ANCHORS), 1.0))
    cols = torch.full((len(X_ANCHORS), len(GEOMETRY.cell_u) + 1), -50.0, dtype=torch.float64)
    cells = np.clip(np.round((u - 3.5) / 8.0).astype(int), 0, len(GEOMETRY.cell_u) - 1)
    cols[torch.arange(len(X_ANCHORS)), torch.from_numpy(cells)] = 50.0
    y, present = decode(cols)
    visible = (u >= 0) & (u < 320)
    err = np.abs(y.numpy() - 1.0)[visible]
    assert (err <= 4.0 * np.abs(GEOMETRY.scale[visible]) + 1e-9).all()  # within half a cell
    assert present.min() > 0.99


@needs_weights
@pytest.mark.parametrize("image", [
    None,
    np.zeros((0, 0, 3), np.uint8),
    np.zeros((160, 320), np.uint8),
    np.zeros((120, 320, 3), np.uint8),
    np.full((160, 320, 3), np.nan, np.float32),
])
def test_bad_frames_give_an_empty_detection(detector, image):
    ld = detector.detect(CameraFrame(3.0, image))
    assert ld.timestamp == 3.0
    assert ld.left is None and ld.right is None and ld.left_prob == 0.0 and ld.right_prob == 0.0


@needs_weights
def test_shipped_weights_on_fresh_held_out_frames(detector, heldout_frames):
    """A few dozen frames rendered now from held-out seeds: D_LD (Alg. 3) close to the true deviation."""
    errors, agree, total = [], 0, 0
    for image, label in heldout_frames:
        ld = detector.detect(CameraFrame(0.0, image))
        d = LdDeviation(0.5).update(ld, label["lane_width"])
        if d is not None:
            errors.append(abs(d - label["deviation"]))
        pairs = ((ld.left_prob, label["left_exists"]), (ld.right_prob, label["right_exists"]))
        for prob, exists in pairs:
            agree += (prob >= 0.5) == exists
            total += 1
    assert len(errors) >= 0.9 * len(heldout_frames)
    assert all(math.isfinite(e) for e in errors)
    assert float(np.mean(errors)) < 0.08
    assert agree / total >= 0.9


def test_anchor_fit_recovers_a_general_cubic_offset():
    """c3 = -2e-5 is 0.2 prior std: the prior's pull on it moves c0 by under 1 cm."""
    coeffs = np.array([1.2, -0.05, 0.004, -2e-5])
    y = torch.tensor(np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs))
    fitted = fit_cubics(y, torch.ones(len(X_ANCHORS), dtype=torch.float64)).numpy()
    assert fitted[0] == pytest.approx(1.2, abs=1e-2)
    assert fitted[1] == pytest.approx(-0.05, abs=3e-3)


def test_cubic_prior_keeps_a_bent_far_end_from_moving_the_offset():
    """A straight line whose two farthest anchors a shadow edge bends away by 0.6 and 1.0 m: plain weighted
    least squares moves c0 by 7 cm, the fit with the c3 prior by under 2 cm."""
    x = np.asarray(X_ANCHORS)
    y = np.full(len(x), 1.7)
    y[-2:] += (0.6, 1.0)
    plain = np.polynomial.polynomial.polyfit(x, y, 3, w=np.sqrt(ANCHOR_WEIGHTS))
    fitted = fit_cubics(torch.tensor(y), torch.ones(len(x), dtype=torch.float64)).numpy()
    assert abs(plain[0] - 1.7) > 0.07
    assert abs(fitted[0] - 1.7) < 0.02


def test_cubic_term_needs_enough_anchors():
    """Below 5 present anchors c3 is held at 0, below 4 also c2: a parabola through 4 anchors stays exact."""
    coeffs = np.array([-1.5, 0.02, 1 / 150, 0.0])
    y = torch.tensor(np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs))
    four = torch.tensor([1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    fitted = fit_cubics(y, four).numpy()
    np.testing.assert_allclose(fitted, coeffs, atol=1e-6)
    three = torch.tensor([1.0] * 3 + [0.0] * (len(X_ANCHORS) - 3), dtype=torch.float64)
    assert fit_cubics(y, three).numpy()[2:] == pytest.approx([0.0, 0.0], abs=1e-6)


@pytest.mark.parametrize("fit", MATRIX_FITS)
def test_cached_fit_matrices_match_the_fit(fit):
    rng = np.random.default_rng(7)
    present = rng.random((5, 2, len(X_ANCHORS))) > 0.3
    y = rng.normal(0.0, 2.0, (5, 2, len(X_ANCHORS)))
    direct = fit_cubics(torch.tensor(y), torch.tensor(present, dtype=torch.float64), fit).numpy()
    np.testing.assert_allclose(np.einsum("nlck,nlk->nlc", fit_matrices(present, fit), y), direct, atol=1e-9)


def test_the_default_fit_is_the_cubic():
    """Without a fit named the decoding is the cubic fit's, to the bit."""
    rng = np.random.default_rng(3)
    cols = torch.tensor(rng.normal(0.0, 3.0, (4, 2, len(X_ANCHORS), len(GEOMETRY.cell_u) + 1)))
    exist = torch.tensor(rng.normal(0.0, 2.0, (4, 2)))
    assert DEFAULT_FIT == "cubic"
    for got, want in zip(lines_from_outputs(cols, exist), lines_from_outputs(cols, exist, "cubic"), strict=True):
        assert got.tobytes() == want.tobytes()
    near = lines_from_outputs(cols, exist, "near")[0]
    assert not np.allclose(near, lines_from_outputs(cols, exist)[0])


@pytest.mark.parametrize("coeffs", [[1.7, 0.03, 0.0, 0.0], [-1.7, 0.0, 1 / 80, 0.0], [1.75, 0.02, -1 / 40, 0.0]])
def test_near_fit_returns_lines_and_arcs_exactly(coeffs):
    """The near fit changes only the anchor weights: c3 = 0 curves come back within 1e-4 (the ridge and prior's
    pull; c0 in m) from all anchors, from the near five and from the far seven."""
    y = torch.tensor(np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs))
    k = len(X_ANCHORS)
    for present in (np.ones(k), np.r_[np.ones(5), np.zeros(k - 5)], np.r_[np.zeros(k - 7), np.ones(7)]):
        fitted = fit_cubics(y, torch.tensor(present), "near").numpy()
        np.testing.assert_allclose(fitted, coeffs, atol=1e-4)


def test_near_fit_bounds_what_a_far_misread_does_at_the_car():
    """A 1 m misread at an anchor 17 m or farther moves the near fit's c0 by at most 0.24 m and c1 by at most
    0.08 (the cubic fit: 0.46 m and 0.14), and at the 30 m anchor c0 by at most 0.06 m (cubic 0.25 m)."""
    k = len(X_ANCHORS)
    far = np.asarray(X_ANCHORS) >= 17.0
    near, cubic = fit_matrices(np.ones(k, bool), "near"), fit_matrices(np.ones(k, bool), "cubic")
    assert np.abs(near[0, far]).max() <= 0.24 and np.abs(near[1, far]).max() <= 0.08
    assert np.abs(cubic[0, far]).max() > 0.45 and np.abs(cubic[1, far]).max() > 0.13
    assert abs(near[0, -1]) <= 0.06 < abs(cubic[0, -1])
    assert (np.abs(near[:2, far]) < np.abs(cubic[:2, far])).all()


def _logits(p: np.ndarray) -> torch.Tensor:
    """Column logits (…, N_COLS + 1) whose softmax is `p` (zeros as -1e9)."""
    return torch.tensor(np.log(np.where(p > 0, p, 1e-300)), dtype=torch.float32)


def test_an_anchors_variance_is_its_column_distributions_in_metres():
    """One column cell: variance 0; two cells 8 px apart with equal mass: (4 px)², in m² at the anchor's scale;
    the absent class does not widen it."""
    k, n = len(X_ANCHORS), len(GEOMETRY.cell_u)
    p = np.zeros((3, k, n + 1))
    p[0, :, 20] = 1.0
    p[1, :, 20] = p[1, :, 21] = 0.5
    p[2, :, 20] = p[2, :, 21] = 0.2
    p[2, :, n] = 0.6
    var = anchor_variance(_logits(p).numpy())
    np.testing.assert_allclose(var[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(var[1], 16.0 * GEOMETRY.scale**2, rtol=1e-9)
    np.testing.assert_allclose(var[2], var[1], rtol=1e-9)


def test_the_spread_fit_with_sharp_anchors_is_the_near_fit_and_numpy_agrees_with_torch():
    rng = np.random.default_rng(11)
    present = rng.random((6, 2, len(X_ANCHORS))) > 0.3
    y = rng.normal(0.0, 2.0, (6, 2, len(X_ANCHORS)))
    sharp = fit_cubics(torch.tensor(y), torch.tensor(present).double(), "spread", torch.zeros(y.shape)).numpy()
    near = fit_cubics(torch.tensor(y), torch.tensor(present).double(), "near").numpy()
    np.testing.assert_allclose(sharp, near, atol=1e-9)
    variance = rng.random(y.shape) * 0.3
    direct = fit_cubics(torch.tensor(y), torch.tensor(present).double(), "spread", torch.tensor(variance)).numpy()
    np.testing.assert_allclose(spread_cubics(y, present, variance), direct, atol=1e-7)
    assert not np.allclose(direct, near, atol=1e-3)
    with pytest.raises(ValueError, match="pass it"):
        fit_cubics(torch.tensor(y), torch.tensor(present).double(), "spread")


@pytest.mark.parametrize("coeffs", [[1.7, 0.03, 0.0, 0.0], [-1.7, 0.0, 1 / 80, 0.0], [1.75, 0.02, -1 / 40, 0.0]])
def test_spread_fit_returns_lines_and_arcs_exactly_whatever_the_spread(coeffs):
    """Anchor spreads up to 0.3 m (the shipped weights' typical at 5–20 m) reweigh exact anchors: c3 = 0 curves come
    back within 1e-3 (c0 in m) from all anchors and from the near five (wider anchors give the c3 prior more pull
    than the near fit's: 0.2 mm at radius 40 m)."""
    y = np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), coeffs)
    variance = (0.3 * np.random.default_rng(2).random(len(X_ANCHORS))) ** 2
    for present in (np.ones(len(X_ANCHORS), bool), np.arange(len(X_ANCHORS)) < 5):
        np.testing.assert_allclose(spread_cubics(y, present, variance), coeffs, atol=1e-3)


def test_a_misread_anchor_the_network_is_unsure_of_moves_the_spread_fit_less():
    """A 1 m misread at the 8 m anchor: with that anchor's spread 0.5 m its pull on c0 is under a fifth of the
    near fit's (the same anchors sharp)."""
    k = len(X_ANCHORS)
    y = np.zeros(k)
    y[3] = 1.0
    present = np.ones(k, bool)
    sure = spread_cubics(y, present, np.zeros(k))
    unsure = spread_cubics(y, present, np.where(np.arange(k) == 3, 0.25, 0.0))
    assert abs(sure[0]) > 0.1 and abs(unsure[0]) < abs(sure[0]) / 5


def test_lines_from_outputs_with_the_spread_fit_follow_the_frames_spread():
    """Decoded through `lines_from_outputs`: the spread fit of each line is `spread_cubics` of its decoded anchors
    and their variances, and it differs from the near fit where the spreads differ."""
    rng = np.random.default_rng(4)
    cols = torch.tensor(rng.normal(0.0, 3.0, (3, 2, len(X_ANCHORS), len(GEOMETRY.cell_u) + 1)), dtype=torch.float32)
    exist = torch.zeros(3, 2)
    coeffs, probs = lines_from_outputs(cols, exist, "spread")
    y, mass = decode(cols)
    want = spread_cubics(y.double().numpy(), mass.numpy() > 0.5, anchor_variance(cols.numpy()))
    np.testing.assert_array_equal(coeffs, want)
    np.testing.assert_array_equal(probs, lines_from_outputs(cols, exist, "near")[1])
    assert not np.allclose(coeffs, lines_from_outputs(cols, exist, "near")[0], atol=1e-3)


def test_an_unknown_fit_is_refused_in_one_line():
    with pytest.raises(UserError, match="unknown lane-line fit 'spline': use one of cubic, near, spread"):
        fit_matrices(np.ones(len(X_ANCHORS), bool), "spline")
    with pytest.raises(UserError, match="the spread fit weighs each frame's anchors by the network's spread: it has "
                                        "no per-mask matrices"):
        fit_matrices(np.ones(len(X_ANCHORS), bool), "spread")


def test_the_detectors_fit_parameter_lists_the_fits():
    from typing import get_args

    from testbed.perception.detectors.registry import NeuralParams

    listed, none = get_args(NeuralParams.model_fields["fit"].annotation)
    assert get_args(listed) == FITS and none is type(None)
    assert NeuralParams.model_fields["fit"].default is None  # unset: the detector's own, DEFAULT_FIT
    assert NeuralLaneDetector(LaneNet()).fit == DEFAULT_FIT


@pytest.mark.parametrize("rows", [56, 112])
def test_frozen_model_gives_the_same_outputs(rows):
    torch.manual_seed(1)
    model = LaneNet(input_rows=rows)
    model.train()
    with torch.no_grad():  # give BatchNorm non-trivial running statistics
        for _ in range(3):
            model(torch.randn(8, 3, rows, 160) * 2.0 + 0.5)
    model.eval()
    fused = FrozenLaneNet(model)
    x = torch.randn(2, 3, rows, 160)
    with torch.inference_mode():
        for a, b in zip(model(x), fused(x), strict=True):
            torch.testing.assert_close(a, b, atol=1e-4, rtol=1e-4)


def test_lanenet_is_built_for_the_listed_input_rows_only():
    with pytest.raises(ValueError, match="input_rows"):
        LaneNet(input_rows=100)
