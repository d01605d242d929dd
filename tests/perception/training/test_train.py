import json

import numpy as np
import pytest
import torch

from testbed.errors import UserError
from testbed.lane_detection import CameraFrame
from testbed.perception.detectors.neural import N_COLS, X_ANCHORS, LaneNet, NeuralLaneDetector, load_model
from testbed.perception.training.dataset import LABEL_KEYS, iter_shards, load_frames, write_shard
from testbed.perception.training.train import TrainConfig, load_tensors, mirror, negative_tensors, to_tensors, train


def _tiny_dataset(path, n=12, shard=0):
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(shard)
    images = [rng.integers(0, 255, (160, 320, 3), dtype=np.uint8) for _ in range(n)]
    labels = [{"left": np.array([1.7, 0.05, 1e-3, 0.0]), "right": np.array([-1.8, 0.05, 1e-3, 0.0]),
               "left_exists": True, "right_exists": bool(i % 2), "lane_width": 3.5, "deviation": 0.05,
               "meta": {"condition": "day", "pose": [0.0, 0.0, 0.0]}} for i in range(n)]
    write_shard(path / f"shard_{shard:05d}.npz", images, labels)


def test_dataset_shards_round_trip(tmp_path):
    _tiny_dataset(tmp_path)
    frames = load_frames(tmp_path)
    assert len(frames) == 12 and frames.images.shape == (12, 160, 320, 3)
    assert frames.right_exists.tolist() == [bool(i % 2) for i in range(12)]
    assert set(LABEL_KEYS) <= set(vars(frames))


def test_the_anchors_are_labelled_where_the_line_lies_and_absent_past_it(tmp_path):
    _tiny_dataset(tmp_path / "cubic", 2)
    cubic = to_tensors(load_frames(tmp_path / "cubic"))  # a dataset written before the anchor labels
    assert load_frames(tmp_path / "cubic").left_anchors is None
    expected_left = np.polynomial.polynomial.polyval(np.asarray(X_ANCHORS), [1.7, 0.05, 1e-3, 0.0])
    torch.testing.assert_close(cubic.y[0, 0].double(), torch.from_numpy(expected_left), atol=1e-5, rtol=0)

    rng = np.random.default_rng(0)
    k = len(X_ANCHORS)
    bent = np.linspace(1.7, 4.0, k)
    bent[-3:] = np.nan  # the line has turned away before the last three anchors
    labels = [{"left": np.array([1.7, 0.05, 1e-3, 0.0]), "right": np.array([-1.8, 0.05, 1e-3, 0.0]),
               "left_anchors": bent, "right_anchors": np.full(k, -1.8), "left_exists": True, "right_exists": True,
               "lane_width": 3.5, "deviation": 0.05, "meta": {}}] * 2
    (tmp_path / "lines").mkdir()
    write_shard(tmp_path / "lines" / "shard_00000.npz",
                [rng.integers(0, 255, (160, 320, 3), dtype=np.uint8) for _ in range(2)], labels)
    frames = load_frames(tmp_path / "lines")
    t = to_tensors(frames)
    torch.testing.assert_close(t.y[0, 0, :-3].double(), torch.from_numpy(bent[:-3]), atol=1e-5, rtol=0)
    torch.testing.assert_close(t.y[0, 1], torch.full((k,), -1.8))
    assert (t.cls[0, 0, -3:] == N_COLS).all() and (t.cls[0, 0, :-3] < N_COLS).all()
    assert (t.y[0, 0, -3:] == 0.0).all()  # never scored: absent
    assert (t.cls[:, 1] < N_COLS).all()

    with np.load(tmp_path / "lines" / "shard_00000.npz") as z:
        stored = {key: z[key] for key in z.files}
    stored["anchor_x"] = stored["anchor_x"] + 1.0
    np.savez(tmp_path / "lines" / "shard_00000.npz", **stored)
    with pytest.raises(UserError, match="render the dataset again"):
        load_frames(tmp_path / "lines")


def test_shards_load_one_at_a_time_up_to_the_limit(tmp_path):
    _tiny_dataset(tmp_path, 5, shard=0)
    _tiny_dataset(tmp_path, 5, shard=1)
    assert [len(f) for f in iter_shards(tmp_path)] == [5, 5]
    assert [len(f) for f in iter_shards(tmp_path, limit=7)] == [5, 2]
    frames = load_frames(tmp_path, limit=7)
    assert len(frames) == 7 and len(frames.meta) == 7
    whole = to_tensors(load_frames(tmp_path, limit=7))
    by_shard = load_tensors([tmp_path], limit=7)
    assert all(torch.equal(getattr(whole, k), getattr(by_shard, k)) for k in ("x", "y", "cls", "c0", "exists"))


def test_mirror_matches_labels_of_the_mirrored_scene(tmp_path):
    _tiny_dataset(tmp_path, 4)
    frames = load_frames(tmp_path)
    mirrored = load_frames(tmp_path)
    mirrored.images = frames.images[:, :, ::-1].copy()
    mirrored.left, mirrored.right = -frames.right, -frames.left
    mirrored.left_exists, mirrored.right_exists = frames.right_exists, frames.left_exists
    flipped, expected = mirror(to_tensors(frames)), to_tensors(mirrored)
    assert torch.equal(flipped.cls, expected.cls)
    torch.testing.assert_close(flipped.y, expected.y)
    torch.testing.assert_close(flipped.c0, expected.c0)
    torch.testing.assert_close(flipped.x.float(), expected.x.float(), atol=1e-2, rtol=0)
    assert torch.equal(flipped.exists, expected.exists)


def test_training_runs_a_few_steps(tmp_path):
    _tiny_dataset(tmp_path / "data")
    res = train([tmp_path / "data"], tmp_path / "out", TrainConfig(epochs=3, batch=4, threads=1),
                val_dir=tmp_path / "data")
    assert res.checkpoint.is_file() and res.curve.is_file()
    assert len(res.history) == 3
    assert all(np.isfinite(h["train_loss"]) for h in res.history)
    torch.manual_seed(0)
    initial = LaneNet().state_dict()
    trained = load_model(res.checkpoint).state_dict()
    assert not torch.equal(initial["columns.weight"], trained["columns.weight"])
    assert json.loads((tmp_path / "out" / "history.json").read_text())[0]["epoch"] == 0
    saved = torch.load(res.checkpoint, weights_only=True)["state_dict"]
    assert all(v.is_contiguous() for v in saved.values())  # trained channels-last, stored NCHW
    det = NeuralLaneDetector(load_model(res.checkpoint))
    ld = det.detect(CameraFrame(0.0, np.zeros((160, 320, 3), np.uint8)))
    assert ld.timestamp == 0.0 and 0.0 <= ld.left_prob <= 1.0 and 0.0 <= ld.right_prob <= 1.0


def test_training_with_every_input_row_kept(tmp_path):
    _tiny_dataset(tmp_path / "data")
    res = train([tmp_path / "data"], tmp_path / "out", TrainConfig(epochs=1, batch=4, threads=1, input_rows=112))
    model = load_model(res.checkpoint)
    assert model.input_rows == 112
    assert to_tensors(load_frames(tmp_path / "data"), 112).x.shape[1:] == (3, 112, 160)
    det = NeuralLaneDetector(model)
    ld = det.detect(CameraFrame(0.0, np.zeros((160, 320, 3), np.uint8)))
    assert 0.0 <= ld.left_prob <= 1.0 and 0.0 <= ld.right_prob <= 1.0
    with pytest.raises(ValueError, match="input_rows=112"):  # a 112-row checkpoint cannot train on at 56 rows
        train([tmp_path / "data"], tmp_path / "out2", TrainConfig(epochs=1, batch=4, threads=1),
              init=res.checkpoint)


def test_negatives_have_no_line_and_every_anchor_absent():
    neg = negative_tensors(6, seed=3)
    assert neg.x.shape == (6, 3, 56, 160) and torch.isfinite(neg.x.float()).all()
    assert (neg.exists == 0).all() and (neg.cls == N_COLS).all() and (neg.c0 == 0).all()
    assert torch.equal(negative_tensors(6, seed=3).x, neg.x) and not torch.equal(negative_tensors(6, seed=4).x, neg.x)


def test_a_fine_tune_with_frozen_batch_norm_keeps_the_starts_statistics(tmp_path):
    _tiny_dataset(tmp_path / "data")
    start = train([tmp_path / "data"], tmp_path / "a", TrainConfig(epochs=1, batch=4, threads=1)).checkpoint
    cfg = TrainConfig(epochs=1, batch=4, threads=1, negatives=4, freeze_bn=True)
    tuned = load_model(train([tmp_path / "data"], tmp_path / "b", cfg, init=start).checkpoint).state_dict()
    before = load_model(start).state_dict()
    assert torch.equal(before["features.0.1.running_mean"], tuned["features.0.1.running_mean"])
    assert not torch.equal(before["features.0.0.weight"], tuned["features.0.0.weight"])
    free = load_model(train([tmp_path / "data"], tmp_path / "c", TrainConfig(epochs=1, batch=4, threads=1),
                            init=start).checkpoint).state_dict()
    assert not torch.equal(before["features.0.1.running_mean"], free["features.0.1.running_mean"])
