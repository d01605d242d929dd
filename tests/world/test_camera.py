"""The front camera: the picture of a scene without a body is drawn once and reused, to the byte, by TinyRenderer
itself (the streamer's render client; the path where the compiled clone is not built) and by the clone."""

import numpy as np
import pybullet as pb
import pytest

import testbed.camera as camera_module
from testbed.camera import FrontCamera
from testbed.conditions import get_condition
from testbed.world import TileStreamer
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle


def _poses(track, stations):
    lane = track.lanes[track.ego_lane]
    return [Pose(*lane.position(s, 0.3), lane.heading_at(s) + 0.02) for s in stations]


def test_a_bodiless_scene_is_rendered_once_and_every_frame_matches_a_fresh_render(monkeypatch):
    track = load_track("slr")  # no roadside body: the render client stays empty
    cond = get_condition("dusk")
    streamer = TileStreamer(track, cond.lighting, clone=False)
    rig = CameraRig(get_vehicle("sedan").camera)
    calls = []
    real = pb.getCameraImage
    monkeypatch.setattr(camera_module.pb, "getCameraImage", lambda *a, **k: calls.append(1) or real(*a, **k))
    try:
        reused = FrontCamera(streamer, rig, cond, np.random.default_rng(7))
        for pose in _poses(track, [20.0, 60.0, 100.0]):
            streamer.update(pose)
            assert pb.getNumBodies(physicsClientId=streamer.client) == 0
            fresh = FrontCamera(streamer, rig, cond, np.random.default_rng(7))
            (rgb, empty), (rgb0, empty0) = reused.scene(pose), fresh.scene(pose)
            assert np.array_equal(rgb, rgb0) and np.array_equal(empty, empty0)
            rgb[:] = 0  # the caller draws on its copy, never on the kept picture
        assert len(calls) == 1 + 3  # the reused camera drew once; each fresh one drew its only frame
    finally:
        streamer.close()


def test_a_scene_with_bodies_is_rendered_every_frame(monkeypatch):
    track = load_track("highway")  # guardrails: roadside bodies in view
    cond = get_condition("day")
    streamer = TileStreamer(track, cond.lighting, clone=False)
    calls = []
    real = pb.getCameraImage
    monkeypatch.setattr(camera_module.pb, "getCameraImage", lambda *a, **k: calls.append(1) or real(*a, **k))
    try:
        cam = FrontCamera(streamer, CameraRig(get_vehicle("sedan").camera), cond, np.random.default_rng(7))
        for pose in _poses(track, [20.0, 40.0]):
            streamer.update(pose)
            assert pb.getNumBodies(physicsClientId=streamer.client) > 0
            cam.render(pose)
        assert len(calls) == 2
    finally:
        streamer.close()


def test_the_clone_draws_a_bodiless_scene_once_too(monkeypatch):
    track = load_track("slr")
    cond = get_condition("night")
    streamer = TileStreamer(track, cond.lighting)
    if streamer.boxes is None:
        streamer.close()
        pytest.skip("the render kernel is not built (or LD3_COMPILED=0)")
    rig = CameraRig(get_vehicle("sedan").camera)
    tiny = TileStreamer(track, cond.lighting, clone=False)
    calls = []
    real = type(streamer.boxes).render
    monkeypatch.setattr(type(streamer.boxes), "render", lambda *a, **k: calls.append(1) or real(*a, **k))
    try:
        reused = FrontCamera(streamer, rig, cond, np.random.default_rng(7))
        reference = FrontCamera(tiny, rig, cond, np.random.default_rng(7))
        for pose in _poses(track, [20.0, 60.0, 100.0]):
            streamer.update(pose)
            tiny.update(pose)
            assert streamer.boxes.body_count == 0
            (rgb, empty), (rgb0, empty0) = reused.scene(pose), reference.scene(pose)
            assert np.array_equal(rgb, rgb0) and np.array_equal(empty, empty0)
            rgb[:] = 0
        assert len(calls) == 1
    finally:
        streamer.close()
        tiny.close()
