"""The camera's frames, byte for byte: digests of frames rendered along the ego lane (tiles streamed, the
ground canvas recentred on the way), recorded from the renderer the lane detector was trained on. A change
that moves one pixel changes the detector's input and every camera run's trajectory."""

import hashlib

import numpy as np
import pytest

from testbed.camera import FrontCamera
from testbed.conditions import get_condition
from testbed.world import TileStreamer
from tracks.pose import Pose
from tracks.presets import load_track
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

STATIONS = (8.0, 50.0, 95.0, 140.0, 185.0, 230.0)

RECORDED = {
    ("urban-straight", "day"): "44e1915f1bf7360085b13baefd5193bca8e2fa8f999c2bda785c8c167d82c210",
    ("local", "dusk"): "8d3c778802f28526a901cede4cc4480335cad99790f05b02ba2d40b66c834da6",
    ("highway", "night"): "bbc916df5f9b63dec22af9ede469abafcdc78b295627c92d7dc548d125a6c3bd",
    ("urban-curvy", "shadows"): "297c5c4d754668ddce6d02d2c7f0ac54a753d2244ec670d4c83b5c23c4036d50",
}


def frames_digest(preset: str, condition: str) -> str:
    track = load_track(preset)
    cond = get_condition(condition)
    track = track.with_painters(cond.track_painters(track.seed))
    streamer = TileStreamer(track, cond.lighting)
    camera = FrontCamera(streamer, CameraRig(get_vehicle("sedan").camera), cond, np.random.default_rng(11))
    lane = track.lanes[track.ego_lane]
    digest = hashlib.sha256()
    try:
        for k, s in enumerate(STATIONS):
            pose = Pose(*lane.position(s, 0.25 * (-1) ** k), lane.heading_at(s) + 0.02 * (-1) ** k)
            streamer.update(pose)
            digest.update(camera.render(pose).tobytes())
    finally:
        streamer.close()
    return digest.hexdigest()


@pytest.mark.parametrize(("preset", "condition"), list(RECORDED))
def test_frames_are_the_recorded_ones_to_the_byte(preset, condition):
    assert frames_digest(preset, condition) == RECORDED[(preset, condition)]
