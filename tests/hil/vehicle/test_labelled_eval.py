"""`ld3 ld eval --labels`: a known line projected into the frame where a pinhole puts it, a resized copy of the
camera's frames read with its calibration scaled, and a hand-made labelled frame scored end to end (its ego lanes
found, a shifted label missed)."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from hil.vehicle.camera_calibration import CameraCalibration
from hil.vehicle.labelled_eval import fitted_calibration, project_line, row_distance
from hil.vehicle.tusimple_metric import ABSENT
from testbed.cli import main
from testbed.errors import UserError
from tests.hil.vehicle.test_camera_detect import CAMERA, LINES, _calibration_file, _camera_view

LEVEL = CameraCalibration(width=1280, height=720, fx=1000.0, fy=1000.0, cx=639.5, cy=359.5, distortion=(),
                          mount_x=0.0, mount_height=1.5, pitch_deg=0.0)


def test_a_straight_line_lands_where_a_pinhole_puts_it():
    rows = np.array([300.0, 359.5, 400.0, 500.0, 600.0, 719.0])
    u = project_line(LEVEL, np.array([1.8]), rows)
    # y = 1.8 m seen from 1.5 m up, level: x = fy h / (v - cy), u = cx - fx y / x
    expected = 639.5 - 1000.0 * 1.8 * (rows[2:] - 359.5) / (1000.0 * 1.5)
    assert u[:2].tolist() == [ABSENT, ABSENT]  # at and above the horizon
    assert u[2:] == pytest.approx(expected, abs=0.05)
    wide = project_line(LEVEL, np.array([3.5]), rows)
    assert wide[2] == pytest.approx(639.5 - 3.5 * 40.5 / 1.5, abs=0.05)
    assert wide[5] == ABSENT  # left of the frame there (u < 0)
    assert row_distance(LEVEL, rows)[2:] == pytest.approx(1500.0 / (rows[2:] - 359.5))
    assert np.isinf(row_distance(LEVEL, rows[:2])).all()


def test_a_resized_copy_of_the_frames_reads_the_calibration_scaled():
    half = fitted_calibration(LEVEL, 640, 360)
    rows = np.array([400.0, 500.0, 600.0])
    full = project_line(LEVEL, np.array([-1.7, 0.01]), rows)
    assert project_line(half, np.array([-1.7, 0.01]), (rows + 0.5) / 2 - 0.5) == pytest.approx((full + 0.5) / 2 - 0.5,
                                                                                                abs=0.02)
    assert fitted_calibration(LEVEL, 1280, 720) is LEVEL
    with pytest.raises(UserError, match="labelled frames are 640x480, the calibration's 1280x720"):
        fitted_calibration(LEVEL, 640, 480)


def _labelled_frame(folder, shift: float = 0.0, scale: int = 1) -> str:
    """CAMERA's view of the test road, with a TuSimple label of its two lines and one beyond (x shifted by `shift`
    px), the picture and label resized by 1/`scale`."""
    folder.mkdir()
    image = _camera_view(CAMERA)
    rows = np.arange(200.0, 360.0, 8.0)
    lanes = [project_line(CAMERA, np.array([y]), rows) for y in (*LINES, LINES[0] + 3.5)]
    small = cv2.resize(image, (CAMERA.width // scale, CAMERA.height // scale), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(folder / "frame.png"), cv2.cvtColor(small, cv2.COLOR_RGB2BGR))
    label = {"raw_file": "frame.png", "h_samples": ((rows + 0.5) / scale - 0.5).tolist(),
             "lanes": [np.where(lane >= 0, (lane + shift + 0.5) / scale - 0.5, ABSENT).tolist() for lane in lanes]}
    (folder / "label.json").write_text(json.dumps(label) + "\n")
    return f"tusimple:{folder / 'label.json'}"


def _eval(tmp_path, labels: str) -> dict:
    calibration = _calibration_file(tmp_path / "cam.toml", CAMERA)
    out = tmp_path / "out"
    assert main(["ld", "eval", "--labels", labels, "--calibration", str(calibration), "--detector", "classical",
                 "--out", str(out)]) == 0
    with open(out / "eval.csv") as f:
        (row,) = list(csv.DictReader(f))
    assert "ego-lane subset" in (out / "report.md").read_text() and (out / "worst_classical_0.png").is_file()
    return row


@pytest.mark.parametrize("scale", [1, 2])
def test_the_ego_lines_of_a_labelled_frame_are_scored_by_the_benchmark(tmp_path, scale):
    row = _eval(tmp_path, _labelled_frame(tmp_path / "frames", scale=scale))
    assert (row["left_found"], row["right_found"], row["left_labelled"], row["right_labelled"]) == ("1",) * 4
    assert float(row["accuracy"]) >= 0.85 and float(row["accuracy_5_30"]) >= 0.95
    assert (float(row["fp"]), float(row["fn"])) == (0.0, 0.0)


def test_a_label_shifted_beyond_the_threshold_is_missed(tmp_path):
    row = _eval(tmp_path, _labelled_frame(tmp_path / "frames", shift=40.0))
    assert float(row["accuracy_5_30"]) == 0.0
    assert (float(row["fp_5_30"]), float(row["fn_5_30"])) == (1.0, 1.0)
