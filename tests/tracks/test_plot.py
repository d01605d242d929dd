import numpy as np
from matplotlib.colors import to_hex
from matplotlib.figure import Figure
from matplotlib.image import imread

from tracks.plot import GROUND_COLOUR, draw_track, save_track_png
from tracks.presets import load_track


def test_save_track_png_writes_a_picture(tmp_path):
    path = save_track_png(load_track("local"), tmp_path / "local.png", s_range=(300.0, 420.0))
    img = imread(path)
    assert img.shape[0] > 500 and img.shape[1] > 500
    assert np.unique(img[::8, ::8].reshape(-1, img.shape[2]), axis=0).shape[0] > 10  # not a blank canvas


def test_draw_track_draws_on_the_given_axes():
    track = load_track("urban-curvy")
    ax = Figure().subplots()
    draw_track(ax, track, s_range=(200.0, 400.0))
    assert ax.lines  # lane lines and edges
    (surfaces,) = [c for c in ax.collections if len(c.get_paths()) == 3]  # right ground, left ground, asphalt
    assert to_hex(surfaces.get_facecolors()[2]) == GROUND_COLOUR["asphalt"]
    x0, x1 = ax.get_xlim()
    xs = track.reference.points(np.array([200.0, 400.0]))[:, 0]
    assert x0 <= xs.min() and x1 >= xs.max()


def test_the_legend_names_the_intersections_once():
    track = load_track("local")  # five zones
    ax = Figure().subplots()
    draw_track(ax, track)
    assert ax.get_legend_handles_labels()[1].count("intersection") == 1
