"""TinyRenderer's compiled clone draws the camera's boxes byte for byte as TinyRenderer does: the same poses on
several roads and in every condition's lighting, with traffic cars, streamed by two streamers (the clone's boxes,
and the render client's bodies), give the same RGBA and the same "nothing drawn" mask."""

from types import ModuleType

import numpy as np
import pybullet as pb
import pytest

from testbed.camera import FrontCamera
from testbed.conditions import CONDITIONS
from testbed.tiny_boxes import TinyBoxes, box_mesh, bullet_rotation, kernel
from testbed.world import TileStreamer
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

needs_kernel = pytest.mark.skipif(kernel() is None, reason="the render kernel is not built (or LD3_COMPILED=0)")

CASES = [("highway", "night", 0), ("urban-curvy", "dusk", 0), ("urban-straight", "day", 0), ("local", "rain", 0),
         ("two-way", "shadows", 4), ("urban-straight", "worn", 3), ("two-way", "night", 4)]


def test_every_condition_is_covered():
    assert set(CONDITIONS) <= {cond for _, cond, _ in CASES}


def test_the_rotation_is_bullets():
    rng = np.random.default_rng(3)
    for q in rng.normal(size=(200, 4)):
        ours = bullet_rotation(q)
        theirs = np.array(pb.getMatrixFromQuaternion(list(q))).reshape(3, 3)
        assert np.array_equal(ours, theirs)


def test_a_removed_body_gives_its_place_to_the_last_one():
    boxes = TinyBoxes(ModuleType("no-kernel"))  # the order only: nothing is drawn
    mesh = box_mesh((1.0, 1.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    keys = [boxes.add([mesh], (0.5, 0.5, 0.5, 1.0)) for _ in range(5)]
    boxes.remove(keys[1])
    boxes.remove(keys[4])  # the last: nothing moves
    assert boxes._order == [keys[0], keys[3], keys[2]]
    key = boxes.add([mesh], (0.5, 0.5, 0.5, 1.0))
    assert boxes._order == [keys[0], keys[3], keys[2], key]


def _poses(track, rng, n):
    """Poses on and beside every lane, headings off the road's, in random order along the road (tiles loaded and
    dropped in every order)."""
    for _ in range(n):
        lane = track.lanes[int(rng.integers(len(track.lanes)))]
        s = float(rng.uniform(2.0, track.length - 5.0))
        x, y = lane.position(s, float(rng.uniform(-2.0, 2.0)))
        yield Pose(x, y, lane.heading_at(s) + (np.pi if lane.oncoming else 0.0) + float(rng.uniform(-0.4, 0.4)))


def _traffic(track, rng, pose_s, count):
    poses = {}
    for i in range(count):
        if rng.uniform() < 0.8:
            lane = track.lanes[int(rng.integers(len(track.lanes)))]
            s = min(max(pose_s + float(rng.uniform(-10.0, 80.0)), 0.0), track.length)
            poses[i] = Pose(*lane.position(s, float(rng.uniform(-0.3, 0.3))),
                            lane.heading_at(s) + float(rng.uniform(-0.3, 0.3)))
    return poses


@needs_kernel
@pytest.mark.parametrize(("preset", "condition", "traffic"), CASES)
def test_the_clone_draws_tinyrenderers_picture(preset, condition, traffic):
    track = load_track(preset)
    cond = CONDITIONS[condition]
    rig = CameraRig(get_vehicle("sedan").camera)
    clone, tiny = TileStreamer(track, cond.lighting), TileStreamer(track, cond.lighting, clone=False)
    assert clone.boxes is not None and tiny.boxes is None
    cameras = [FrontCamera(s, rig, cond, np.random.default_rng(0)) for s in (clone, tiny)]
    car = get_vehicle("sedan")
    if traffic:
        for s in (clone, tiny):
            s.add_traffic(traffic, car.length, car.width, car.height)
    rng = np.random.default_rng(len(preset) + 7 * traffic)
    drawn = 0
    try:
        for pose in _poses(track, rng, 24):
            for s in (clone, tiny):
                s.update(pose)
            if traffic:
                poses = _traffic(track, rng, track.reference.project(pose.x, pose.y)[0], traffic)
                for s in (clone, tiny):
                    s.place_traffic(poses)
            (rgba_c, empty_c), (rgba_t, empty_t) = (cam.scene(pose) for cam in cameras)
            assert np.array_equal(empty_c, empty_t)
            assert np.array_equal(rgba_c, rgba_t)
            assert np.array_equal(cameras[0].render(pose), cameras[1].render(pose))
            drawn += int((~empty_t).sum())
    finally:
        clone.close()
        tiny.close()
    assert drawn > 0 or preset == "local"
