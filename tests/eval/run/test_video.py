"""camera.mp4: H.264 in yuv420p at the camera rate, padded to even size, the overlay drawn into the frames."""

import imageio_ffmpeg
import numpy as np
import pytest

from testbed.eval.run.video import FrameSignals, VideoWriter
from testbed.lane_detection import CameraFrame, LaneDetection
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

H, W = 161, 321  # odd on purpose: yuv420p needs even sizes, so the writer pads to 162 × 322
N = 30


def synthetic_image() -> np.ndarray:
    """Sky over a grey road, smooth enough for the codec to keep it within a few grey levels."""
    img = np.empty((H, W, 3), np.uint8)
    img[:60] = (150, 180, 220)
    img[60:] = (90, 90, 90)
    return img


def decode(path) -> tuple[dict, np.ndarray]:
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    w, h = meta["size"]
    return meta, np.stack([np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in frames])


@pytest.fixture
def rig() -> CameraRig:
    return CameraRig(get_vehicle("sedan").camera)


def test_the_video_is_h264_yuv420p_at_the_camera_rate_with_the_overlay_drawn(tmp_path, rig):
    image = synthetic_image()
    ld = LaneDetection(0.0, np.array([1.8, 0.0, 0.0, 0.0]), np.array([-1.8, 0.0, 0.0, 0.0]), 1.0, 1.0, (2.0, 40.0))
    writer = VideoWriter(rig, fps=20.0)
    for i in range(N):
        t = i / 20.0
        ar = i >= N // 2
        writer.add(CameraFrame(t, image), ld, FrameSignals(t, 0.1, 1.5 if ar else 0.2, 2.0 if ar else 0.1, 1.2,
                                                           "ar" if ar else "normal"))
    path = tmp_path / "camera.mp4"
    writer.write(path)

    meta, frames = decode(path)
    assert meta["codec"] == "h264"
    assert meta["pix_fmt"].startswith("yuv420p")
    assert meta["fps"] == 20.0
    assert meta["size"] == (W + 1, H + 1)
    assert len(frames) == N
    band = np.s_[:30, :W]  # the signals band across the sky
    raw_band = image[band].astype(float)
    assert np.abs(frames[0][band] - raw_band).mean() > 40.0
    road = np.s_[H - 20:H, 100:220]  # below the band, between the drawn lines
    assert np.abs(frames[0][road] - image[road].astype(float)).mean() < 6.0
    normal, ar = frames[N // 2 - 1].astype(float), frames[N // 2].astype(float)
    assert np.abs(ar[band] - normal[band]).max() > 100.0  # mode, D_MSF and the CUSUM bar changed
    red = ar[band]
    assert ((red[..., 0] > 180) & (red[..., 1] < 120)).sum() > 100  # CUSUM above τ: the bar is red


def test_a_run_without_frames_writes_no_video_and_a_resized_frame_is_refused(tmp_path, rig):
    writer = VideoWriter(rig)
    writer.write(tmp_path / "camera.mp4")
    assert not (tmp_path / "camera.mp4").exists()
    signals = FrameSignals(0.0, None, None, None, None, "normal")
    writer.add(CameraFrame(0.0, synthetic_image()), LaneDetection.empty(0.0), signals)
    with pytest.raises(ValueError, match="size changed"):
        writer.add(CameraFrame(0.05, np.zeros((80, 160, 3), np.uint8)), LaneDetection.empty(0.05), signals)
    writer.close()


def test_the_same_frames_give_the_same_bytes(tmp_path, rig):
    for name in ("a.mp4", "b.mp4"):
        writer = VideoWriter(rig)
        for i in range(10):
            writer.add(CameraFrame(i / 20.0, synthetic_image()), LaneDetection.empty(i / 20.0),
                       FrameSignals(i / 20.0, 0.1 * i, -0.1 * i, 0.05 * i, 1.2, "normal"))
        writer.write(tmp_path / name)
    assert (tmp_path / "a.mp4").read_bytes() == (tmp_path / "b.mp4").read_bytes()
