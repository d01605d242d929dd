"""Scoring of a lane detector against labelled frames: D_LD error per condition and preset, existence P/R, report."""

import json

import numpy as np
import pytest

from testbed.lane_detection import LaneDetection, LaneDetector
from testbed.perception.training.dataset import load_frames, write_shard
from testbed.perception.training.evaluate import evaluate, markdown_table, write_report
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

LEFT, RIGHT = np.array([1.6, 0.0, 0.0, 0.0]), np.array([-1.9, 0.0, 0.0, 0.0])  # lane 3.5 m, car 0.15 m left


def _frames(tmp_path):
    images = [np.full((160, 320, 3), 90, np.uint8) for _ in range(4)]
    metas = [("day", "slr"), ("day", "highway"), ("rain", "slr"), ("rain", "highway")]
    kinds = [{"left_kind": "dashed_white", "right_kind": "solid_white"}] * 2
    kinds += [{"left_kind": "solid_white", "right_kind": "none"}, {}]
    labels = [{"left": LEFT, "right": RIGHT, "left_exists": True, "right_exists": i != 3, "lane_width": 3.5,
               "deviation": 0.15, "meta": {"condition": c, "preset": p, "pose": [0.0, 0.0, 0.0], **kinds[i]}}
              for i, (c, p) in enumerate(metas)]
    tmp_path.mkdir(parents=True)
    write_shard(tmp_path / "shard_00000.npz", images, labels)
    return load_frames(tmp_path)


class ShiftedLeftLine(LaneDetector):
    """Test double: the true left line moved 0.1 m outward; the right line reported on frames 0-1 only."""

    def detect(self, frame) -> LaneDetection:
        right = RIGHT if frame.t < 2 else None
        return LaneDetection(frame.t, LEFT + np.array([0.1, 0, 0, 0]), right, 0.9, 0.9 if right is not None else 0.1,
                             (0.0, 30.0))


def test_errors_existence_and_report(tmp_path):
    frames = _frames(tmp_path / "data")
    report, dets = evaluate(ShiftedLeftLine(), frames)
    # the left line (1.7 m) is nearer than the right (1.9 m): D_LD = 1.75 - 1.7 = 0.05, truth 0.15
    assert report["frame_errors_m"] == pytest.approx([0.1] * 4)
    assert report["overall"]["mean_abs_err_m"] == pytest.approx(0.1)
    assert set(report["per_condition"]) == {"day", "rain"} and set(report["per_preset"]) == {"slr", "highway"}
    # the car is left of centre, so the left line is the nearer one; frame 3 predates recorded kinds
    near = {k: v["frames"] for k, v in report["per_near_line"].items()}
    assert near == {"dashed_white": 2, "solid_white": 1, "?": 1}
    assert {k: v["frames"] for k, v in report["per_occlusion"].items()} == {"clear": 4}
    # right line: said on 0, 1 (true), missing on 2 (wrongly: it exists) and 3 (rightly)
    rain = report["per_condition"]["rain"]
    assert rain["missing_lines"] == 1 and rain["missing_recall"] == 1.0 and rain["missing_precision"] == 0.5
    assert report["per_condition"]["day"]["missing_precision"] is None  # nothing said missing by day
    paths = write_report([report], (frames, dets, CameraRig(get_vehicle("sedan").camera)), tmp_path / "out")
    assert {"json", "markdown", "grid", "cdf"} <= set(paths) and all(p.is_file() for p in paths.values())
    assert json.loads(paths["json"].read_text())[0]["per_preset"]["slr"]["frames"] == 2
    md = paths["markdown"].read_text()
    assert "| ShiftedLeftLine | rain | 2 | 0.100 |" in md and "| ShiftedLeftLine | highway | 2 | 0.100 |" in md
    assert "| ShiftedLeftLine | dashed_white | 2 | 0.100 |" in md


def test_existence_errors_by_visible_fraction_and_label_repeatability(tmp_path):
    frames = _frames(tmp_path / "data")
    visible = [[0.9, 0.5], [0.3, 0.2], [0.9, 0.16], [0.9, None]]
    redrawn = [[[True, True], [False, True]], [[True, False], [True, True]], [[True, True], [True, False]],
               [[True, False], [True, False]]]
    for meta, v, r in zip(frames.meta, visible, redrawn, strict=True):
        meta.update(visible=v, redrawn_exists=r)
    report, _ = evaluate(ShiftedLeftLine(), frames)
    bands = {r["visible_fraction"]: r for r in report["existence_by_visible_fraction"]}
    assert [b["lines"] for b in bands.values()] == [1, 0, 0, 2, 1, 1, 3]
    # the one wrong call: frame 2's right line (visible in 0.16 of its rows) said missing
    assert bands["0.15-0.25"] == {"visible_fraction": "0.15-0.25", "lines": 2, "labelled_present": 2,
                                  "said_present_labelled_missing": 0, "said_missing_labelled_present": 1}
    assert bands["not judged"]["labelled_present"] == 0
    noise = report["label_repeatability"]
    assert noise["draws"] == 2 and noise["lines"] == 8 and noise["lines_flipped_in_any_draw"] == 3
    assert noise["flip_rate"] == pytest.approx(3 / 16)
    assert noise["flip_rate_per_condition"] == pytest.approx({"day": 2 / 8, "rain": 1 / 8})
    # the redraws call 3 present lines missing and agree on the one missing line (twice)
    sc = noise["redrawn_labels_scored"]
    assert sc["missing_precision"] == pytest.approx(2 / 5) and sc["missing_recall"] == 1.0
    assert sc["present_precision"] == 1.0 and sc["present_recall"] == pytest.approx(11 / 14)
    md = write_report([report], None, tmp_path / "out")["markdown"].read_text()
    assert "| 0.15-0.25 | 2 | 2 | 0 | 1 |" in md and "0.188 of labels flip per draw (day 0.250, rain 0.125)" in md


def test_frames_are_scored_apart_where_traffic_hides_their_lines(tmp_path):
    frames = _frames(tmp_path / "data")
    for meta, hidden in zip(frames.meta, (0.25, 0.0, None, 0.5), strict=True):
        meta.update(traffic=3, occluded=hidden)
    report, _ = evaluate(ShiftedLeftLine(), frames)
    groups = report["per_occlusion"]
    assert groups["occluded"]["frames"] == 2 and groups["clear"]["frames"] == 2
    assert groups["occluded"]["mean_abs_err_m"] == pytest.approx(0.1)
    assert "| ShiftedLeftLine | occluded | 2 | 0.100 |" in markdown_table([report])


def test_datasets_without_visibility_records_report_none(tmp_path):
    report, _ = evaluate(ShiftedLeftLine(), _frames(tmp_path / "data"))
    assert report["existence_by_visible_fraction"] is None and report["label_repeatability"] is None
