"""The compiled asphalt layer paints the same bytes as the numpy reference, on tiles of every preset (intersections,
curbs and dividers, each roadside ground) and with painter settings off the default."""

from unittest import mock

import numpy as np
import pytest

import tracks.paint as paint
from tracks.compiled import compiled_module
from tracks.paint import AsphaltPainter
from tracks.presets import PRESETS, load_track
from tracks.texture import tile_frame

KERNEL = compiled_module("tracks.paint_kernels")
compiled = pytest.mark.skipif(KERNEL is None, reason="the Cython kernels are not built (no C compiler at install)")


def _painted(painter: AsphaltPainter, track, i: int, reference: bool) -> np.ndarray:
    frame = tile_frame(track, i)
    img = np.zeros((frame.height, frame.width, 3), np.uint8)
    if reference:
        with mock.patch.object(paint, "_KERNELS", None):
            painter.paint(img, frame, np.random.default_rng([track.seed, i]))
    else:
        painter.paint(img, frame, np.random.default_rng([track.seed, i]))
    return img


@compiled
@pytest.mark.parametrize("preset", PRESETS)
def test_kernel_paints_the_reference_bytes(preset):
    track = load_track(preset)
    painter = track.painters[0]
    assert isinstance(painter, AsphaltPainter)
    tiles = range(0, track.n_tiles, max(1, track.n_tiles // 12))
    crossings = [i for i in range(track.n_tiles) if any(track.in_intersection(s) for s in
                                                        tile_frame(track, i).s_of_rows()[::25])][:3]
    for i in sorted({*tiles, *crossings, track.n_tiles - 1}):
        assert np.array_equal(_painted(painter, track, i, False), _painted(painter, track, i, True)), (preset, i)


@compiled
@pytest.mark.parametrize(("tone", "grain", "tone_variation"), [(0.5, 30.0, 0.4), (3.0, 60.0, 0.9)])
def test_kernel_clips_and_truncates_as_the_reference(tone, grain, tone_variation):
    """Dark and bright tones with strong grain; the brightest reaches both ends of the byte range."""
    track = load_track("local")
    painter = AsphaltPainter(tone, grain, tone_variation)
    for i in (0, 7, 31):
        kernel, reference = _painted(painter, track, i, False), _painted(painter, track, i, True)
        assert np.array_equal(kernel, reference), i
        if tone > 1.0:
            assert reference.min() == 0 and reference.max() == 255
