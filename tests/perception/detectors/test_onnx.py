import numpy as np
import pytest
import torch

from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.neural import FRAME_SHAPE, INPUT_WIDTH, LaneNet, NeuralLaneDetector, load_model

pytest.importorskip("onnxruntime")

from testbed.perception.detectors.onnx_runtime import OnnxLaneDetector, OnnxLaneNet, export_onnx


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_the_onnx_export_matches_torch(model, tmp_path):
    data = export_onnx(model, tmp_path / "lanenet.onnx")
    assert (tmp_path / "lanenet.onnx").read_bytes() == data
    net = OnnxLaneNet(data)
    for x in np.random.default_rng(0).normal(size=(4, 1, 3, model.input_rows, INPUT_WIDTH)).astype(np.float32):
        with torch.no_grad():
            cols, exist = model(torch.from_numpy(x))
        ort_cols, ort_exist = net(x)
        np.testing.assert_allclose(ort_cols, cols.numpy(), atol=1e-4, rtol=0)
        np.testing.assert_allclose(ort_exist, exist.numpy(), atol=1e-4, rtol=0)


def test_the_onnx_detector_gives_the_torch_detection(model):
    rng = np.random.default_rng(1)
    image = rng.integers(0, 255, (*FRAME_SHAPE, 3), dtype=np.uint8)
    image[100:, 150:160] = 255  # a bright stripe for the network to find
    frame = CameraFrame(0.5, image)
    ours, torch_ld = OnnxLaneDetector(model).detect(frame), NeuralLaneDetector(model).detect(frame)
    assert ours.left_prob == pytest.approx(torch_ld.left_prob, abs=1e-4)
    assert ours.right_prob == pytest.approx(torch_ld.right_prob, abs=1e-4)
    for a, b in ((ours.left, torch_ld.left), (ours.right, torch_ld.right)):
        assert (a is None) == (b is None)
        if a is not None:
            np.testing.assert_allclose(a, b, atol=1e-4)
    assert OnnxLaneDetector(model).detect(CameraFrame(0.0, None)).left is None


def test_a_112_row_network_exports_and_detects_as_in_torch():
    torch.manual_seed(2)
    model = LaneNet(input_rows=112).eval()
    x = np.random.default_rng(3).normal(size=(1, 3, 112, INPUT_WIDTH)).astype(np.float32)
    with torch.no_grad():
        cols, exist = model(torch.from_numpy(x))
    ort_cols, ort_exist = OnnxLaneNet(export_onnx(model))(x)
    np.testing.assert_allclose(ort_cols, cols.numpy(), atol=1e-4, rtol=0)
    np.testing.assert_allclose(ort_exist, exist.numpy(), atol=1e-4, rtol=0)
    image = np.random.default_rng(4).integers(0, 255, (*FRAME_SHAPE, 3), dtype=np.uint8)
    ours, torch_ld = OnnxLaneDetector(model).detect(CameraFrame(0.0, image)), NeuralLaneDetector(model).detect(
        CameraFrame(0.0, image))
    assert ours.left_prob == pytest.approx(torch_ld.left_prob, abs=1e-4)
    assert ours.right_prob == pytest.approx(torch_ld.right_prob, abs=1e-4)


def test_the_neural_detector_runs_onnxruntime_unless_told_torch(model):
    from testbed.perception.detectors.registry import make_detector

    image = np.random.default_rng(5).integers(0, 255, (*FRAME_SHAPE, 3), dtype=np.uint8)
    frame = CameraFrame(0.25, image)
    default = make_detector("neural", track=None, rig=None)
    assert isinstance(default, OnnxLaneDetector)
    torch_ld = make_detector("neural", track=None, rig=None, params={"runtime": "torch"})
    assert isinstance(torch_ld, NeuralLaneDetector)
    ours, reference = default.detect(frame), OnnxLaneDetector(model).detect(frame)
    assert np.array_equal(ours.left, reference.left) and ours.left_prob == reference.left_prob
    assert np.array_equal(ours.right, reference.right) and ours.right_prob == reference.right_prob


@pytest.mark.parametrize("fit", ["near", "spread"])
@pytest.mark.parametrize("name", ["neural", "neural-onnx"])
def test_the_neural_detectors_fit_their_anchors_as_told(model, name, fit):
    from testbed.perception.detectors.registry import make_detector

    frame = CameraFrame(0.0, np.random.default_rng(6).integers(0, 255, (*FRAME_SHAPE, 3), dtype=np.uint8))
    told = make_detector(name, track=None, rig=None, params={"fit": fit})
    assert told.fit == fit and make_detector(name, track=None, rig=None).fit == "cubic"
    reference = NeuralLaneDetector(model, fit=fit).infer(frame.image)[0]
    np.testing.assert_allclose(told.infer(frame.image)[0], reference, atol=1e-3)


def test_one_session_per_network_in_a_process(model):
    from testbed.perception.detectors.onnx_runtime import model_digest, session_for

    again = load_model()
    assert model_digest(again) == model_digest(model) and session_for(again) is session_for(model)
    torch.manual_seed(6)
    other = LaneNet().eval()
    assert model_digest(other) != model_digest(model) and session_for(other) is not session_for(model)
    assert session_for(model, threads=2) is not session_for(model)


def test_without_onnxruntime_the_neural_detector_names_the_extra_and_the_torch_runtime(model, monkeypatch):
    import sys

    from testbed.errors import UserError
    from testbed.perception.detectors import onnx_runtime

    monkeypatch.setitem(sys.modules, "onnxruntime", None)
    monkeypatch.setattr(onnx_runtime, "_SESSIONS", {})
    with pytest.raises(UserError, match=r"ld3-testbed\[nn\].*detector\.runtime"):
        OnnxLaneDetector(model)


def test_a_built_detector_has_paid_the_first_frame_and_detects_as_a_fresh_one(model):
    """Building it infers a blank frame: the fit's per-mask matrices exist before the first camera frame, and the
    detections are those of a detector that saw nothing before."""
    from testbed.perception.detectors import neural

    neural._fit_matrices.cache_clear()
    built = OnnxLaneDetector(model, fit="near")
    assert neural._fit_matrices.cache_info().currsize == 1
    rng = np.random.default_rng(2)
    frames = [CameraFrame(0.05 * k, rng.integers(0, 255, (*FRAME_SHAPE, 3), dtype=np.uint8)) for k in range(3)]
    for frame in frames:
        a, b = built.detect(frame), OnnxLaneDetector(model, fit="near").detect(frame)
        assert (a.left_prob, a.right_prob) == (b.left_prob, b.right_prob)
        for la, lb in ((a.left, b.left), (a.right, b.right)):
            assert (la is None and lb is None) or np.array_equal(la, lb)
