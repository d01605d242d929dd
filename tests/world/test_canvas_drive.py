"""The ground canvas over a drive, byte for byte: digests of the whole canvas (its pixels, origin and tiles) each
time the streamer changes the tiles it holds, along 400 m of the ego lane (tiles painted, lit, warped, erased and
the canvas recentred), recorded from the build the lane detector's frames come from. A change that moves one canvas
pixel moves the camera's frames."""

import hashlib

import numpy as np
import pytest

from testbed.conditions import get_condition
from testbed.world import TileStreamer
from tracks.pose import Pose
from tracks.presets import load_track

DRIVE_M, STEP_M = 400.0, 6.0

RECORDED = {
    ("urban-straight", "day"): "21d03a85be42e54af7901883de189e131c0aafe87f62a9816ea1c5b1f1450d33",
    ("urban-curvy", "shadows"): "659aa4ceda86a85ff389845135f997e14bbf5ebd1d8d80924e5404c4e5cc87af",
    ("local", "worn"): "91ee5e9d4ea93fde67ceadf98bb862e0e343c106e2c4c35c63381ea0eb16d2f1",
    ("highway", "night"): "917bae48b6b382b50b0ee5d69cf68152ee3126d2aa78071e63d27bb1cc61b5fa",
    ("two-way", "rain"): "689ebcec7dda4f871c69520f29d7daefc89e69c8e9d8ebbe5b19376b53c88081",
}


def canvas_digest(preset: str, condition: str, drive_m: float = DRIVE_M) -> str:
    track = load_track(preset)
    cond = get_condition(condition)
    track = track.with_painters(cond.track_painters(track.seed))
    streamer = TileStreamer(track, cond.lighting)
    lane = track.lanes[track.ego_lane]
    digest, held = hashlib.sha256(), None
    try:
        for s in np.arange(0.5, min(drive_m, lane.length - 1.0), STEP_M):
            pose = Pose(*lane.position(s, 0.0), lane.heading_at(s))
            streamer.update(pose)
            canvas = streamer.canvas
            if canvas.tiles != held:
                held = set(canvas.tiles)
                digest.update(repr((sorted(held), canvas.origin, canvas.image.shape)).encode())
                digest.update(canvas.image.tobytes())
    finally:
        streamer.close()
    return digest.hexdigest()


@pytest.mark.parametrize(("preset", "condition"), list(RECORDED))
def test_canvas_over_a_drive_is_the_recorded_one_to_the_byte(preset, condition):
    assert canvas_digest(preset, condition) == RECORDED[(preset, condition)]
