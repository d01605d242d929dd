"""Camera reader: a video file through OpenCV arrives frame by frame at its rate, a camera that stops is a stall;
a calibration file rectifies a camera's frames into the detector's rig."""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

from hil.camera_calibration import CameraCalibration, Rectifier
from hil.camera_reader import CameraReader, HandedFrames, OpenCvSource
from vehicles.camera_rig import CameraRig
from vehicles.params import CameraParams

RIG = CameraRig(CameraParams())


def _video(path, frames: int = 8, fps: float = 20.0):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (64, 32))
    for k in range(frames):
        writer.write(np.full((32, 64, 3), 20 * k + 10, np.uint8))
    writer.release()


def test_a_video_file_plays_at_its_rate_and_its_end_is_a_stall(tmp_path):
    _video(tmp_path / "drive.avi")
    start = time.monotonic()
    reader = CameraReader(OpenCvSource(f"video:{tmp_path / 'drive.avi'}"), lambda: time.monotonic() - start,
                          stall_s=0.3)
    try:
        assert reader.wait_frame(8, timeout=5.0)
        elapsed = time.monotonic() - start
        frame = reader.capture(elapsed)
        assert frame.image.shape == (32, 64, 3) and abs(int(frame.image[0, 0, 0]) - 150) < 8
        assert reader.capture(elapsed).image is None  # nothing new since
        assert elapsed >= 0.3  # paced at 20 fps, not read at once
        time.sleep(0.1)
        assert reader.ended == "end of stream" and reader.stalled(elapsed) is None
        assert reader.stalled(elapsed + 0.5).startswith("no camera frame for")
    finally:
        reader.close()


def test_bad_camera_specs_are_user_errors(tmp_path):
    with pytest.raises(ValueError, match="v4l2:/dev/videoN or video:PATH"):
        OpenCvSource("usb:0")
    with pytest.raises(ValueError, match="cannot open camera"):
        OpenCvSource(f"video:{tmp_path / 'missing.avi'}")


def test_handed_frames_that_stop_coming_stall_the_camera():
    now = [0.0]
    frames = HandedFrames()
    reader = CameraReader(frames, lambda: now[0], stall_s=0.5)
    try:
        frames.put(np.zeros((4, 4, 3), np.uint8))
        assert reader.wait_frame(1, 2.0) and reader.capture(0.0).image is not None
        now[0] = 0.4
        assert reader.stalled(0.4) is None and reader.stalled(0.6).startswith("no camera frame for 0.60 s")
    finally:
        reader.close()


def _calibration(tmp_path, pitch_deg: float, distortion: str = "[]") -> CameraCalibration:
    k = RIG.K
    (tmp_path / "cam.toml").write_text(
        f"[intrinsics]\nwidth = {RIG.width}\nheight = {RIG.height}\nfx = {k[0, 0]}\nfy = {k[1, 1]}\ncx = {k[0, 2]}\n"
        f"cy = {k[1, 2]}\ndistortion = {distortion}\n[extrinsics]\nmount_x = 1.1\nmount_height = 1.3\n"
        f"pitch_deg = {pitch_deg}\n")
    return CameraCalibration.load(tmp_path / "cam.toml")


def test_a_camera_calibrated_as_the_rig_is_passed_through_and_a_pitch_moves_the_horizon(tmp_path):
    image = np.zeros((RIG.height, RIG.width, 3), np.uint8)
    image[100, :] = 255
    same = _calibration(tmp_path, RIG.params.pitch_deg)
    assert same.rig_params(RIG.params).mount_x == 1.1
    out = Rectifier(same, RIG)(image)
    assert int(np.argmax(out[:, 160, 0])) == 100
    steeper = Rectifier(_calibration(tmp_path, RIG.params.pitch_deg + 2.0), RIG)(image)
    row = int(np.argmax(steeper[:, 160, 0]))
    # the camera looks 2° further down: what it sees at row 100 lies 2° further below the rig's axis
    f, cy = RIG.K[1, 1], RIG.K[1, 2]
    assert row == pytest.approx(cy + f * np.tan(np.arctan((100 - cy) / f) + np.radians(2.0)), abs=1.0)
    with pytest.raises(ValueError, match="frame is 160x80, its calibration 320x160"):
        Rectifier(_calibration(tmp_path, 5.0), RIG)(np.zeros((80, 160, 3), np.uint8))


def test_a_broken_calibration_file_names_what_is_wrong(tmp_path):
    (tmp_path / "cam.toml").write_text("[intrinsics]\nwidth = 320\n")
    with pytest.raises(ValueError, match="missing or bad entry"):
        CameraCalibration.load(tmp_path / "cam.toml")
    with pytest.raises(ValueError, match="distortion takes"):
        _calibration(tmp_path, 5.0, "[0.1, 0.2]")
