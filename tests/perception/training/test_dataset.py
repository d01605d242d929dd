from pathlib import Path

import numpy as np
import pytest

from testbed.conditions import CONDITIONS
from testbed.perception.detectors.labels import VISIBLE_FRACTION
from testbed.perception.detectors.neural import X_ANCHORS
from testbed.perception.training.dataset import build_dataset, episodes, erase_stretches, render_episode
from testbed.perception.training.seeds import HELD_OUT_SEEDS, TRAIN_SEEDS
from tracks.geometry import Arc, Straight
from tracks.layout import MARKING_KINDS
from tracks.presets import PRESETS


def test_held_out_seeds_are_disjoint_from_training_seeds():
    assert not set(TRAIN_SEEDS) & set(HELD_OUT_SEEDS)
    train = episodes("train", 2 * len(PRESETS) * len(CONDITIONS), 0)
    held = episodes("heldout", len(PRESETS) * len(CONDITIONS), 0)
    assert all(ep.seed in TRAIN_SEEDS for ep in train)
    assert all(ep.seed in HELD_OUT_SEEDS for ep in held)
    assert {(ep.preset, ep.condition) for ep in held} == {(p, c) for p in PRESETS for c in CONDITIONS}
    with pytest.raises(ValueError):
        episodes("test", 3, 0)


def test_episodes_can_be_drawn_in_chosen_conditions_only():
    n = 4 * len(PRESETS)
    chosen = episodes("train", n, 5, ["night", "worn"])
    assert {(ep.preset, ep.condition) for ep in chosen} == {(p, c) for p in PRESETS for c in ("night", "worn")}
    assert [ep.seed for ep in chosen] == [ep.seed for ep in episodes("train", n, 5)]  # same track seeds
    assert episodes("train", n, 5, list(CONDITIONS)) == episodes("train", n, 5)
    for bad in (["fog"], [], ["night", "night"]):
        with pytest.raises(ValueError, match="conditions"):
            episodes("train", 3, 0, bad)


def test_episodes_can_be_drawn_on_chosen_presets_only():
    chosen = episodes("train", 8, 5, ["worn"], ["slr", "urban-curvy"])
    assert [ep.preset for ep in chosen] == ["slr", "urban-curvy"] * 4
    assert {ep.condition for ep in chosen} == {"worn"}
    assert episodes("train", 8, 5, presets=list(PRESETS)) == episodes("train", 8, 5)
    for bad in (["mars"], [], ["slr", "slr"]):
        with pytest.raises(ValueError, match="presets"):
            episodes("train", 3, 0, presets=bad)


def test_corner_roads_are_rendered_only_when_named_and_turn_tight_without_transitions():
    assert "corners" not in {ep.preset for ep in episodes("train", 40, 1)}
    chosen = episodes("train", 4, 1, ["day"], ["corners"])
    assert {ep.preset for ep in chosen} == {"corners"}
    track = chosen[0].build_track()
    assert track.name == "corners" and track.length >= 900.0
    bends = [seg for seg in track.reference.segments if not isinstance(seg, Straight)]
    assert bends and all(isinstance(seg, Arc) and 15.0 <= abs(seg.radius) <= 50.0 for seg in bends)
    assert {seg.radius > 0 for seg in bends} == {True, False}  # corners both ways
    again = chosen[0].build_track()
    assert [(type(a), a.length) for a in track.reference.segments] == [
        (type(b), b.length) for b in again.reference.segments]
    assert chosen[1].build_track().reference.length != track.length  # another seed, another road
    image, label = next(render_episode(chosen[0], 1))
    assert image.shape == (160, 320, 3) and label["meta"]["preset"] == "corners"


def test_erased_stretches_keep_the_runs_tiling_the_road(track):
    before = [b.t for b in track.boundaries]
    erase_stretches(track, np.random.default_rng(4), per_km=20.0)
    assert [b.t for b in track.boundaries] == before
    erased = 0.0
    for b in track.boundaries:
        assert b.runs[0].s0 == 0.0 and b.runs[-1].s1 == pytest.approx(track.length)
        for r0, r1 in zip(b.runs, b.runs[1:], strict=False):
            assert r0.s1 == pytest.approx(r1.s0)
        erased += sum(r.s1 - r.s0 for r in b.runs if r.kind == "none")
    assert erased > 100.0


def test_same_episode_renders_the_same_bytes():
    from testbed.perception.training.dataset import Episode, render_episode

    ep = Episode("local", TRAIN_SEEDS[41], "night")
    first, second = (list(render_episode(ep, 3)) for _ in range(2))
    assert len(first) == 3
    for (img_a, lab_a), (img_b, lab_b) in zip(first, second, strict=True):
        assert img_a.tobytes() == img_b.tobytes()
        np.testing.assert_array_equal(lab_a["left"], lab_b["left"])
        np.testing.assert_array_equal(lab_a["left_anchors"], lab_b["left_anchors"])
        assert lab_a["meta"] == lab_b["meta"]
        for side in ("left", "right"):  # on a straight local road the line lies on its cubic at every anchor
            at = lab_a[f"{side}_anchors"]
            assert at.shape == (len(X_ANCHORS),) and np.isfinite(at).all()
            np.testing.assert_allclose(at, np.polynomial.polynomial.polyval(X_ANCHORS, lab_a[side]), atol=0.1)
        meta = lab_a["meta"]  # the rig jitter and the line markings are recorded for per-frame analysis
        assert abs(meta["pitch_jitter_deg"]) <= 0.5 and abs(meta["height_jitter_m"]) <= 0.05
        assert {meta["left_kind"], meta["right_kind"]} <= set(MARKING_KINDS)
        for v, exists in zip(meta["visible"], (lab_a["left_exists"], lab_a["right_exists"]), strict=True):
            assert (v is None and not exists) or (0.0 <= v <= 1.0 and exists == (v >= VISIBLE_FRACTION))


def test_label_redraws_leave_the_frames_and_labels_unchanged():
    from testbed.perception.training.dataset import Episode, render_episode

    ep = Episode("urban-straight", TRAIN_SEEDS[7], "worn")
    plain = list(render_episode(ep, 2))
    redrawn = list(render_episode(ep, 2, label_draws=3))
    for (img_a, lab_a), (img_b, lab_b) in zip(plain, redrawn, strict=True):
        assert img_a.tobytes() == img_b.tobytes()
        draws = lab_b["meta"].pop("redrawn_exists")
        assert lab_a["meta"] == lab_b["meta"] and "redrawn_exists" not in lab_a["meta"]
        assert len(draws) == 3 and all(len(d) == 2 and all(isinstance(x, bool) for x in d) for d in draws)
    with pytest.raises(ValueError, match="label_draws"):
        build_dataset(Path("unused"), 2, label_draws=-1)


def test_traffic_shows_cars_at_the_same_poses_and_records_what_they_hide():
    from testbed.perception.training.dataset import Episode, render_episode

    ep = Episode("urban-curvy", TRAIN_SEEDS[12], "day")
    plain = list(render_episode(ep, 4))
    busy = list(render_episode(ep, 4, traffic=6))
    assert busy[0][0].tobytes() == next(iter(render_episode(ep, 4, traffic=6)))[0].tobytes()
    for (_, lab_a), (_, lab_b) in zip(plain, busy, strict=True):
        meta = dict(lab_b["meta"])
        assert 1 <= meta.pop("traffic") <= 6 and 0.0 <= meta.pop("occluded") <= 1.0
        assert {k: v for k, v in meta.items() if k != "visible"} == {k: v for k, v in lab_a["meta"].items()
                                                                     if k != "visible"}
        assert lab_a["deviation"] == lab_b["deviation"]
    assert any(img_a.tobytes() != img_b.tobytes() for (img_a, _), (img_b, _) in zip(plain, busy, strict=True))
    assert any(lab["meta"]["occluded"] > 0.0 for _, lab in busy)
    with pytest.raises(ValueError, match="--traffic"):
        build_dataset(Path("unused"), 2, traffic=-1)


def test_traffic_on_a_road_too_short_for_every_car_places_what_fits():
    from testbed.perception.training.dataset import OTHERS_RANGE_M, TRAFFIC_CAR, traffic_poses
    from tracks.presets import load_track
    from vehicles.params import get_vehicle

    track = load_track(f"slr@{TRAIN_SEEDS[0]}")
    assert len(track.lanes) == 1
    car = get_vehicle(TRAFFIC_CAR)
    fits = int((OTHERS_RANGE_M[1] - OTHERS_RANGE_M[0]) / (car.length + 1.0)) + 2
    poses = traffic_poses(track, track.lanes[0], 100.0, 3 * fits, np.random.default_rng(0), car.length)
    assert 1 <= len(poses) <= fits
    gaps = np.diff(sorted(track.lanes[0].reference.project(p.x, p.y)[0] for p in poses))
    assert (gaps > car.length).all()


def test_episodes_can_be_drawn_on_map_routes_and_label_the_maps_lanes(tmp_path):
    from testbed.errors import UserError
    from testbed.perception.training.dataset import Episode, render_episode
    from tracks.opendrive.write import write_xodr
    from tracks.presets import load_track

    preset = load_track(f"urban-straight@{TRAIN_SEEDS[3]}")
    path = tmp_path / "exported.xodr"
    write_xodr(preset, path)
    spec = f"xodr:{path}"
    chosen = episodes("train", 4, 5, ["day", "rain"], tracks=[spec])
    assert [(ep.preset, ep.track, ep.condition) for ep in chosen] == [
        ("exported", spec, "day"), ("exported", spec, "rain")] * 2
    assert [ep.seed for ep in chosen] == [ep.seed for ep in episodes("train", 4, 5)]  # the frames' draws
    frames = list(render_episode(Episode("exported", TRAIN_SEEDS[3], "day", spec), 4))
    assert len(frames) == 4
    for _, label in frames:
        assert label["meta"]["track"] == spec and label["meta"]["preset"] == "exported"
        if label["left_exists"] and label["right_exists"]:  # the map's own lane, read from the exported file
            assert label["left"][0] - label["right"][0] == pytest.approx(label["lane_width"], abs=0.2)
            assert label["lane_width"] == pytest.approx(preset.lanes[0].width, abs=0.05)
    for bad in ([f"urban-straight@{TRAIN_SEEDS[3]}"], [], [spec, spec]):
        with pytest.raises(UserError, match="tracks must be distinct map routes"):
            episodes("train", 3, 0, tracks=bad)
    with pytest.raises(UserError, match="either presets or map tracks"):
        episodes("train", 3, 0, presets=["slr"], tracks=[spec])


def test_rendering_datasets_needs_no_torch():
    import subprocess
    import sys

    code = "import sys, testbed.perception.training.dataset; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"  # torch is the optional `nn` extra: labels are made without it
