"""`ld3 ld detect`: a camera alone through the calibration into the detector; the deviation comes out in metres
of the vehicle frame whatever the camera's mount, and a frame that does not fit is refused in one line."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

from hil.vehicle.camera_calibration import CameraCalibration
from testbed.cli import main
from vehicles.camera_rig import CameraRig
from vehicles.params import get_vehicle

RIG = CameraRig(get_vehicle("sedan").camera)
LINES = (1.6, -1.9)  # m: the ego lines, so the car is 0.15 m left of the lane centre
CAMERA = CameraCalibration(width=640, height=360, fx=560.0, fy=556.0, cx=322.0, cy=185.0,
                           distortion=(-0.2, 0.04, 0.0, 0.0, 0.0), mount_x=1.3, mount_height=1.23, pitch_deg=-1.5,
                           mount_y=0.1, yaw_deg=-1.2, roll_deg=0.8)


def _road(ground: np.ndarray) -> np.ndarray:
    """Colour (N, 3) of flat-ground points (N, 2): grey asphalt, white 15 cm lines at `LINES`, NaN is sky."""
    out = np.tile(np.array([[150, 190, 230]], np.uint8), (len(ground), 1))
    ok = np.isfinite(ground).all(axis=1) & (ground[:, 0] > 0.0)
    out[ok] = (90, 90, 95)
    for y in LINES:
        out[ok & (np.abs(ground[:, 1] - y) < 0.075)] = (235, 235, 235)
    return out


def _camera_view(calibration: CameraCalibration) -> np.ndarray:
    """What the calibrated camera sees of that road (its distortion applied)."""
    v, u = np.mgrid[0 : calibration.height, 0 : calibration.width].astype(np.float64)
    pixels = np.column_stack([u.ravel(), v.ravel()])[:, None, :]
    normal = cv2.undistortPoints(pixels, calibration.matrix, np.array(calibration.distortion))[:, 0, :]
    rays = np.column_stack([normal, np.ones(len(normal))]) @ calibration.vehicle_from_camera.T
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(rays[:, 2] < -1e-9, -calibration.mount_height / rays[:, 2], np.nan)
    ground = calibration.mount[:2] + s[:, None] * rays[:, :2]
    return _road(ground).reshape(calibration.height, calibration.width, 3)


def _rig_view() -> np.ndarray:
    v, u = np.mgrid[0 : RIG.height, 0 : RIG.width].astype(np.float64)
    ground = RIG.pixel_to_ground(np.column_stack([u.ravel(), v.ravel()]))
    return _road(ground).reshape(RIG.height, RIG.width, 3)


def _pictures(folder, image: np.ndarray, n: int = 3) -> str:
    folder.mkdir()
    for k in range(n):
        cv2.imwrite(str(folder / f"{k:03d}.png"), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    return f"images:{folder}/*.png"


def _calibration_file(path, c: CameraCalibration):
    path.write_text(f"[intrinsics]\nwidth = {c.width}\nheight = {c.height}\nfx = {c.fx}\nfy = {c.fy}\ncx = {c.cx}\n"
                    f"cy = {c.cy}\ndistortion = {list(c.distortion)}\n[extrinsics]\nmount_x = {c.mount_x}\n"
                    f"mount_y = {c.mount_y}\nmount_height = {c.mount_height}\npitch_deg = {c.pitch_deg}\n"
                    f"yaw_deg = {c.yaw_deg}\nroll_deg = {c.roll_deg}\n")
    return path


def _rows(out) -> list[dict]:
    with open(out / "detections.csv") as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("detector", ["classical", "neural"])
def test_a_calibrated_camera_at_its_own_mount_reads_the_lane_in_vehicle_metres(tmp_path, detector):
    camera = _pictures(tmp_path / "frames", _camera_view(CAMERA))
    calibration = _calibration_file(tmp_path / "cam.toml", CAMERA)
    out = tmp_path / "out"
    assert main(["ld", "detect", "--camera", camera, "--calibration", str(calibration), "--out", str(out),
                 "--detector", detector, "--overlay", "images"]) == 0
    rows = _rows(out)
    assert [r["t"] for r in rows] == ["0.0000", "0.0500", "0.1000"]
    for r in rows:
        assert r["left_found"] == r["right_found"] == "1"
        assert float(r["dev_raw_m"]) == pytest.approx(0.15, abs=0.06)
        assert float(r["dev_m"]) == pytest.approx(0.15, abs=0.06)
        assert float(r["lane_width_m"]) == pytest.approx(3.5, abs=0.12)
    assert sorted(p.name for p in (out / "overlay").iterdir()) == ["000000.png", "000001.png", "000002.png"]
    assert "both lines found | 3 (100%)" in (out / "report.md").read_text() and (out / "dev.png").is_file()


def test_the_rig_view_needs_no_calibration(tmp_path):
    camera = _pictures(tmp_path / "frames", _rig_view(), n=2)
    assert main(["ld", "detect", "--camera", camera, "--out", str(tmp_path / "out"), "--detector", "classical",
                 "--overlay", "none", "--no-tracking"]) == 0
    assert [float(r["dev_raw_m"]) for r in _rows(tmp_path / "out")] == pytest.approx([0.15, 0.15], abs=0.05)


def test_frames_that_do_not_fit_the_detector_are_refused_in_one_line(tmp_path, capsys):
    camera = _pictures(tmp_path / "frames", _camera_view(CAMERA), n=1)
    assert main(["ld", "detect", "--camera", camera, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("ld3: error: camera frames are 640x360 but the detector reads the 320x160 view of its own rig: "
                   "give --calibration CAL.toml (docs/camera.md)")
    calibration = _calibration_file(tmp_path / "cam.toml", CameraCalibration(**{**CAMERA.__dict__, "width": 1280}))
    assert main(["ld", "detect", "--camera", camera, "--calibration", str(calibration), "--out",
                 str(tmp_path / "out")]) == 2
    assert "camera frames are 640x360, the calibration's 1280x360" in capsys.readouterr().err
    for spec, why in (("usb:0", "--camera takes video:FILE, v4l2:DEV or images:GLOB"),
                      (f"images:{tmp_path}/none*.png", "no image matches"),
                      (f"video:{tmp_path}/missing.mp4", "cannot open camera")):
        assert main(["ld", "detect", "--camera", spec, "--out", str(tmp_path / "out")]) == 2
        assert why in capsys.readouterr().err
    assert main(["ld", "detect", "--camera", camera, "--out", str(tmp_path / "out"), "--detector", "oracle"]) == 2
    assert "does not read a camera" in capsys.readouterr().err


def test_a_video_is_stamped_by_its_rate_and_its_overlay_is_a_video(tmp_path):
    path = tmp_path / "drive.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (RIG.width, RIG.height))
    for _ in range(4):
        writer.write(cv2.cvtColor(_rig_view(), cv2.COLOR_RGB2BGR))
    writer.release()
    out = tmp_path / "out"
    assert main(["ld", "detect", "--camera", f"video:{path}", "--out", str(out), "--detector", "classical"]) == 0
    rows = _rows(out)
    assert [r["t"] for r in rows] == ["0.0000", "0.1000", "0.2000", "0.3000"]
    assert all(r["left_found"] == r["right_found"] == "1" for r in rows)
    assert (out / "overlay.mp4").stat().st_size > 0
