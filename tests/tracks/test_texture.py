import numpy as np
import pytest

from tracks.paint import PatchPainter, ShadowPainter, WearPainter, marking_coverage
from tracks.presets import load_track
from tracks.texture import MAX_TEXTURE_SIDE, tile_frame, tile_mesh, tile_texture


@pytest.fixture(scope="module")
def curvy():
    return load_track("urban-curvy@2")


def test_textures_are_deterministic_per_seed_and_tile(curvy):
    a = tile_texture(curvy, 12)
    assert a.dtype == np.uint8 and a.ndim == 3 and a.shape[2] == 3
    np.testing.assert_array_equal(a, tile_texture(load_track("urban-curvy@2"), 12))
    assert not np.array_equal(a, tile_texture(curvy, 13)[: a.shape[0], : a.shape[1]])


def test_texture_sizes_are_bounded_and_resolution_default():
    for name in ("highway", "parking-lot"):
        f = tile_frame(load_track(name), 0)
        assert f.height <= MAX_TEXTURE_SIDE and f.width <= MAX_TEXTURE_SIDE
    f = tile_frame(load_track("highway"), 3)
    assert f.px_per_m_s == pytest.approx(25.0) and f.px_per_m_t == pytest.approx(25.0, rel=0.01)


def test_markings_are_bright_on_the_lines_and_dark_between(curvy):
    track = load_track("slr")
    frame = tile_frame(track, 5)
    img = tile_texture(track, 5)
    grey = img.mean(axis=2)
    row = frame.height // 2
    col_line = round(frame.pixel(0.0, track.boundaries[0].t)[1] - 0.5)
    col_centre = round(frame.pixel(0.0, 0.0)[1] - 0.5)
    assert grey[row, col_line] > 200 and grey[row, col_centre] < 130


def test_dashes_are_three_metres_on_nine_off():
    track = load_track("highway")
    frame = tile_frame(track, 10)
    cov = marking_coverage(frame)
    col = round(frame.pixel(0.0, track.boundaries[1].t)[1] - 0.5)
    on = cov[:, col] > 0.5
    s = frame.s_of_rows()
    phase = np.mod(s, 12.0)
    clear = (np.abs(phase - 3.0) > 0.05) & (phase > 0.05) & (phase < 11.95)
    np.testing.assert_array_equal(on[clear], phase[clear] < 3.0)
    assert on.sum() / frame.px_per_m_s == pytest.approx(6.0, abs=0.1)  # s in [200, 220): dashes at 204, 216


def test_patch_changes_pixels_only_inside_it():
    track = load_track("urban-straight")
    before = tile_texture(track, 4)
    track = track.with_painters(
        [PatchPainter(s_center=90.0, t_center=0.5, length=4.0, width=2.0, angle=0.0, darkness=0.8)]
    )
    after = tile_texture(track, 4)
    frame = tile_frame(track, 4)
    s = frame.s_of_rows()[:, None]
    t = frame.t_of_cols()[None, :]
    inside = (np.abs(s - 90.0) < 1.95) & (np.abs(t - 0.5) < 0.95)
    outside = (np.abs(s - 90.0) > 2.05) | (np.abs(t - 0.5) > 1.05)
    changed = np.any(before != after, axis=2)
    assert changed[inside].all()
    assert not changed[outside].any()
    assert after[inside].mean() < before[inside].mean() - 30


def test_wear_fades_markings_and_shadows_darken(curvy):
    track = load_track("slr")
    clean = tile_texture(track, 3).astype(float)
    cov = marking_coverage(tile_frame(track, 3)) > 0.9
    track = track.with_painters([WearPainter(0.8)])
    worn = tile_texture(track, 3).astype(float)
    assert worn[cov].mean() < clean[cov].mean() - 40
    np.testing.assert_array_equal(
        worn[~(marking_coverage(tile_frame(track, 3)) > 0)],
        clean[~(marking_coverage(tile_frame(track, 3)) > 0)],
    )
    track = track.with_painters([ShadowPainter(darkness=0.6, per_100m=10.0)])
    shaded = np.mean([tile_texture(track, i).mean() for i in range(3, 8)])
    assert shaded < np.mean([tile_texture(load_track("slr"), i).mean() for i in range(3, 8)]) - 3


def test_mesh_uvs_map_world_points_to_their_texture_pixels(curvy):
    i = 20
    vertices, uvs, indices = tile_mesh(curvy, i)
    frame = tile_frame(curvy, i)
    assert vertices.shape[1] == 3 and np.all(vertices[:, 2] == 0.0)
    assert indices.ndim == 1 and len(indices) % 3 == 0 and indices.max() < len(vertices)
    for k in (0, 37, len(vertices) - 1):
        s, t = curvy.reference.project(vertices[k, 0], vertices[k, 1])
        row, col = frame.pixel(s, t)
        assert uvs[k] == pytest.approx((col / frame.width, row / frame.height), abs=1e-6)
    tri = vertices[indices.reshape(-1, 3)]
    normal_z = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    assert np.all(normal_z > 0.0)
