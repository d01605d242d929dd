"""The exported detector graph (frame in, lines out) detects as the torch detector does, and runs where torch and
OpenCV are not installed (detector neural-onnx with detector.weights = the .onnx file)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.neural import FRAME_SHAPE, NeuralLaneDetector, load_model
from testbed.perception.detectors.onnx_file import FRAME_SHAPE as FILE_FRAME_SHAPE

pytest.importorskip("onnxruntime")

from testbed.perception.detectors.onnx_file import OnnxFileLaneDetector
from testbed.perception.training.onnx_detector_graph import export_detector_onnx


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    path = tmp_path_factory.mktemp("onnx") / "lanenet.onnx"
    export_detector_onnx(load_model(), path)
    return path


def _lines_agreeing(ours, reference, frames) -> int:
    """Asserts both detectors give every frame the same lines (existence, range, cubics within 1e-4); returns how
    many lines were compared."""
    lines = 0
    for image, _ in frames:
        a, b = ours.detect(CameraFrame(0.0, image)), reference.detect(CameraFrame(0.0, image))
        assert a.left_prob == pytest.approx(b.left_prob, abs=1e-4)
        assert a.right_prob == pytest.approx(b.right_prob, abs=1e-4)
        assert a.x_range == b.x_range
        for x, y in ((a.left, b.left), (a.right, b.right)):
            assert (x is None) == (y is None)
            if x is not None:
                np.testing.assert_allclose(x, y, atol=1e-4)
                lines += 1
    return lines


def test_the_detector_graph_detects_as_the_torch_detector(graph, heldout_frames):
    assert (*FRAME_SHAPE, 3) == FILE_FRAME_SHAPE
    ours, reference = OnnxFileLaneDetector(graph), NeuralLaneDetector(load_model())
    assert _lines_agreeing(ours, reference, heldout_frames) > 20
    assert ours.detect(CameraFrame(0.0, None)).left is None


def test_a_network_only_file_is_refused_with_the_fix(tmp_path):
    from testbed.perception.detectors.onnx_runtime import export_onnx

    export_onnx(load_model(), tmp_path / "net.onnx")
    with pytest.raises(ValueError, match="not a detector graph"):
        OnnxFileLaneDetector(tmp_path / "net.onnx")


def test_the_detector_graph_runs_without_torch_and_opencv(graph, heldout_frames, tmp_path):
    image = heldout_frames[3][0]
    np.save(tmp_path / "frame.npy", image)
    probe = textwrap.dedent(f"""
        import importlib.abc, sys
        class Refuse(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path, target=None):
                if name.split(".")[0] in ("torch", "cv2", "pybullet", "matplotlib"):
                    raise ModuleNotFoundError(name)
        sys.meta_path.insert(0, Refuse())
        import numpy as np
        from testbed.lane_detection import CameraFrame
        from testbed.perception.detectors.registry import make_detector
        detector = make_detector("neural-onnx", track=None, rig=None, params={{"weights": "{graph}"}})
        ld = detector.detect(CameraFrame(0.0, np.load("{tmp_path / 'frame.npy'}")))
        print(ld.left_prob, ld.right_prob)
    """)
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    expected = NeuralLaneDetector(load_model()).detect(CameraFrame(0.0, image))
    left, right = (float(v) for v in done.stdout.split())
    assert left == pytest.approx(expected.left_prob, abs=1e-4) and right == pytest.approx(expected.right_prob, abs=1e-4)


def test_a_graph_exported_with_the_near_fit_detects_as_the_torch_detector_with_it(heldout_frames, tmp_path):
    path = tmp_path / "near.onnx"
    export_detector_onnx(load_model(), path, fit="near")
    ours, reference = OnnxFileLaneDetector(path, fit="near"), NeuralLaneDetector(load_model(), fit="near")
    assert ours.fit == "near"
    assert _lines_agreeing(ours, reference, heldout_frames[:10]) > 5
    from testbed.perception.detectors.registry import DETECTORS, make_detector

    unset = {"weights": str(path)}  # no detector.fit: the graph's own, and the resolved settings claim none
    assert make_detector("neural-onnx", track=None, rig=None, params=unset).fit == "near"
    assert DETECTORS.get("neural-onnx").settings(unset, "detector neural-onnx").fit is None


def test_a_graph_is_refused_for_a_fit_it_was_not_exported_with(graph):
    assert OnnxFileLaneDetector(graph).fit == "cubic"
    with pytest.raises(ValueError, match="exported with the cubic fit, not near"):
        OnnxFileLaneDetector(graph, fit="near")
    with pytest.raises(ValueError, match="not spread: the spread fit is solved per frame outside any graph: set "
                                         r"detector\.weights to the checkpoint"):
        OnnxFileLaneDetector(graph, fit="spread")


def test_the_spread_fit_is_not_exported_into_a_graph(tmp_path):
    from testbed.perception.detectors.neural import MATRIX_FITS
    from testbed.perception.detectors.onnx_file import GRAPH_FITS

    assert GRAPH_FITS == MATRIX_FITS
    with pytest.raises(UserError, match="the spread fit is solved per frame and cannot be baked into a detector "
                                        "graph: export with --fit cubic or near"):
        export_detector_onnx(load_model(), tmp_path / "spread.onnx", fit="spread")
    assert not (tmp_path / "spread.onnx").exists()
