"""`ld3 ld detect` (the lane detector on a camera alone, hil.vehicle.camera_detect) and `ld3 ld eval --labels` (on
labelled real frames, hil.vehicle.labelled_eval), added to the `ld` command group."""

from __future__ import annotations

import argparse
from pathlib import Path

from hil.vehicle.frame_stream import SPECS

DEFAULT_SPEED = 25.0


def add_detect_parser(ld: argparse.ArgumentParser) -> None:
    """Add `detect` to the `ld` group's subcommands."""
    from testbed.perception.detectors.registry import DETECTORS

    sub = next(a for a in ld._actions if isinstance(a, argparse._SubParsersAction))
    p = sub.add_parser("detect", help="run a lane detector on a camera, video or pictures alone (no GNSS or CAN)",
                       description="Detect and track the ego lines in every frame; write DIR/detections.csv, an "
                                   "overlay of the detector's view and DIR/report.md with the deviation's plot.")
    p.add_argument("--camera", required=True, metavar=SPECS.replace(", ", "|").replace(" or ", "|"),
                   help="a video file, a V4L2 device or pictures (sorted by name)")
    p.add_argument("--calibration", type=Path, help="camera calibration TOML (docs/camera.md); without it the "
                                                     "frames must be the detector rig's own 320x160 view")
    p.add_argument("--out", type=Path, required=True, metavar="DIR")
    p.add_argument("--detector", default="neural", choices=DETECTORS.names())
    p.add_argument("--weights", help="neural checkpoint: a path or a shipped name (default: the shipped weights)")
    p.add_argument("--fps", type=float, default=20.0, help="frame rate of pictures (and of a video that gives none)")
    p.add_argument("--speed", type=float, default=DEFAULT_SPEED, metavar="M/S",
                   help=f"the car's speed the tracker assumes (no odometry on a camera alone; default "
                        f"{DEFAULT_SPEED:g}, a highway speed): it carries the lines along their heading between "
                        f"frames; 0 holds them still, which lags a lane change by over 0.5 s")
    p.add_argument("--no-tracking", dest="tracking", action="store_false", help="report the detector's lines as is")
    p.add_argument("--overlay", choices=("video", "images", "none"), default="video",
                   help="overlay.mp4, overlay/NNNNNN.png or nothing (default video)")
    p.add_argument("--frames", type=int, help="stop after this many frames")
    p.set_defaults(func=_detect)


def _detect(args: argparse.Namespace) -> int:
    from hil.vehicle.camera_detect import DetectConfig, run_detect
    from testbed.errors import UserError
    from testbed.eval.run.folder import check_out_dir, output_folder
    from testbed.perception.detectors.registry import DETECTORS, make_detector
    from testbed.registry import Capability
    from vehicles.camera_rig import CameraRig
    from vehicles.params import get_vehicle

    if args.frames is not None and args.frames < 1:
        raise UserError(f"--frames must be at least 1, got {args.frames}")
    if args.speed < 0:
        raise UserError(f"--speed must be >= 0 m/s, got {args.speed:g}")
    if Capability.CAMERA_IMAGE not in DETECTORS.get(args.detector).provides:
        raise UserError(f"detector {args.detector} does not read a camera: use neural, neural-onnx or classical")
    params = {"weights": args.weights} if args.weights else {}
    rig = CameraRig(get_vehicle("sedan").camera)
    detector = make_detector(args.detector, track=None, rig=rig, params=params)
    check_out_dir(args.out, True, "detections.csv", "a detection pass")
    with output_folder(args.out, True, "detections.csv", "a detection pass") as tmp:
        config = DetectConfig(camera=args.camera, out=tmp, calibration=args.calibration, detector=args.detector,
                              weights=args.weights, fps=args.fps, speed=args.speed, tracking=args.tracking,
                              overlay=args.overlay, limit=args.frames)
        s = run_detect(config, detector, rig)
    step = s["dev_m_p95_step"]
    print(f"{s['frames']} frames, both lines on {s['both_lines']} ({s['both_share']:.0%}); p95 frame-to-frame "
          f"change of dev_m {'-' if step is None else f'{step:.3f} m'}; wrote {args.out}/detections.csv, report.md")
    if s["view_warning"]:
        print(f"warning: {s['view_warning']}")
    return 0


def add_labels_arguments(ld: argparse.ArgumentParser) -> None:
    """Give the `ld` group's `eval` the labelled real frames: `--labels FORMAT:PATH` and `--calibration`."""
    sub = next(a for a in ld._actions if isinstance(a, argparse._SubParsersAction))
    p = sub.choices["eval"]
    p.add_argument("--labels", metavar="tusimple:PATH",
                   help="score on labelled real frames instead of --data: a TuSimple label file (JSON lines, raw_file "
                        "relative to it) or a folder of them; the benchmark's metric on the ego lanes "
                        "(docs/camera.md)")
    p.add_argument("--calibration", type=Path, help="with --labels: the camera's calibration TOML (docs/camera.md); "
                                                     "a resized copy of its frames reads it scaled")
    p.set_defaults(func=_eval_dispatch(p.get_default("func")))


def _eval_dispatch(simulated):
    """`ld eval`: the labelled real frames with --labels, else the simulated held-out dataset (`simulated`)."""

    def run(args: argparse.Namespace) -> int:
        from testbed.errors import UserError

        if args.labels is None:
            if args.calibration is not None:
                raise UserError("--calibration goes with --labels")
            return simulated(args)
        if args.data is not None:
            raise UserError("give --data (simulated frames) or --labels (labelled real frames), not both")
        return _labelled_eval(args)

    return run


def _labelled_eval(args: argparse.Namespace) -> int:
    from hil.vehicle.labelled_eval import LabelledEvalConfig, load_inputs, run_labelled_eval
    from testbed.errors import UserError
    from testbed.eval.run.folder import check_out_dir, output_folder
    from testbed.perception.commands import at_least
    from testbed.perception.detectors.registry import make_detector
    from vehicles.camera_rig import CameraRig
    from vehicles.params import get_vehicle

    if args.calibration is None:
        raise UserError("--labels needs --calibration CAL.toml (docs/camera.md; docs/cameras/tusimple.toml for "
                        "TuSimple frames)")
    at_least(args.limit, 1, "--limit")
    config = LabelledEvalConfig(labels=args.labels, calibration=args.calibration, detectors=tuple(args.detector),
                                weights=str(args.weights) if args.weights else None, limit=args.limit)
    frames, calibration = load_inputs(config)
    rig = CameraRig(get_vehicle("sedan").camera)
    params = {"weights": config.weights} if config.weights else {}

    def detector(name: str):
        return make_detector(name, track=None, rig=rig, params=params if name == "neural" else {})

    check_out_dir(args.out, True, "eval.csv", "a labelled evaluation")
    with output_folder(args.out, True, "eval.csv", "a labelled evaluation") as tmp:
        summary = run_labelled_eval(config, frames, calibration, detector, rig, tmp, progress=True)
    for name, s in summary.items():
        print(f"{name}: {s['frames']} frames, both lines on {s['both_found']}; ego lanes: accuracy "
              f"{s['accuracy']:.3f}, "
              f"FP {s['fp']:.3f}, FN {s['fn']:.3f} (5-30 m: {s['accuracy_5_30']:.3f}, {s['fp_5_30']:.3f}, "
              f"{s['fn_5_30']:.3f})")
    print(f"wrote {args.out}/eval.csv, report.md")
    return 0
