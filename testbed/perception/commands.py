"""`ld3 ld dataset|train|average|existence-refit|eval|export-onnx|closed-loop`: lane-detector tooling subcommands
(argparse), registered by testbed/cli.py (hil adds `ld3 ld detect`)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_ld_parser(subparsers) -> argparse.ArgumentParser:
    """Register `ld` with its `dataset`, `train`, `average`, `existence-refit`, `eval`, `export-onnx` and
    `closed-loop` subcommands; each sets `func(args) -> int`."""
    ld = subparsers.add_parser("ld", help="lane detector: render datasets, train, evaluate")
    sub = ld.add_subparsers(dest="ld_command", required=True)

    p = sub.add_parser("dataset", help="render labelled camera frames from the presets or from map routes")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--frames", type=int, required=True)
    p.add_argument("--split", choices=("train", "heldout"), default="train")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--frames-per-episode", type=int, default=30)
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--conditions", nargs="+", metavar="CONDITION",
                   help="render episodes in these camera conditions only (default: all, cycled evenly)")
    tracks = p.add_mutually_exclusive_group()
    tracks.add_argument("--presets", nargs="+", metavar="PRESET",
                        help="render episodes of these track presets only (default: all, cycled evenly); also "
                             "'corners', town roads of tight corners rendered for training only")
    tracks.add_argument("--tracks", nargs="+", metavar="xodr:FILE[#ROUTE]",
                        help="render episodes on these OpenDRIVE routes instead of the presets (cycled evenly; "
                             "the seed draws the frames' places along each route)")
    p.add_argument("--label-draws", type=int, default=0, metavar="K",
                   help="also label each frame under K other draws of the sensor's exposure, blur and noise; "
                        "`ld3 ld eval` then reports how repeatable the existence labels are")
    p.add_argument("--traffic", type=_cars, default=0, metavar="N",
                   help="up to N traffic cars in each frame, most often a lead car 3-25 m ahead in the ego lane "
                        "(default 0: none)")
    p.set_defaults(func=_dataset)

    p = sub.add_parser("train", help="train LaneNet from scratch on CPU")
    p.add_argument("--data", type=Path, nargs="+", required=True, help="training dataset directories")
    p.add_argument("--val", type=Path, help="held-out dataset directory (scored every epoch)")
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--minutes", type=float, default=27.0, help="training time budget (wall clock, after loading)")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--limit", type=int, help="use at most this many frames per directory")
    p.add_argument("--init", type=Path, help="continue from this checkpoint instead of from scratch")
    p.add_argument("--lr", type=float, default=3e-3, help="peak learning rate")
    p.add_argument("--input-rows", type=int, choices=(56, 112), default=56,
                   help="network input rows: the ground crop's halved (the shipped weights) or all kept")
    p.add_argument("--negatives", type=int, default=0,
                   help="frames without lane lines (noise, dark, blur, textures) added, both lines absent")
    p.add_argument("--freeze-bn", action="store_true", help="keep the batch-norm statistics of --init")
    p.set_defaults(func=_train)

    p = sub.add_parser("average", help="write the element-wise mean of LaneNet checkpoints of one shape (a weight "
                                       "average of fine-tunes from one start)")
    p.add_argument("checkpoints", type=Path, nargs="+", metavar="CHECKPOINT")
    p.add_argument("--out", type=Path, required=True)
    p.set_defaults(func=_average)

    p = sub.add_parser("existence-refit", help="refit a LaneNet's existence outputs alone, with frames without lane "
                                               "lines (noise, dark, blur, textures) as negatives; lines unchanged")
    p.add_argument("--init", type=Path, help="checkpoint to start from (default: the shipped weights)")
    p.add_argument("--data", type=Path, nargs="+", required=True, help="simulation datasets: the positives")
    p.add_argument("--negatives", type=int, default=2000, help="frames without lane lines drawn (default 2000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the negatives' draws")
    p.add_argument("--out", type=Path, required=True, help="checkpoint to write")
    p.set_defaults(func=_existence_refit)

    p = sub.add_parser("eval", help="score detectors on held-out frames per condition (or, with the hil package, "
                                    "on labelled real frames: --labels)")
    p.add_argument("--data", type=Path, help="held-out dataset directory (required without --labels)")
    p.add_argument("--detector", nargs="+", choices=("neural", "classical"), default=["neural", "classical"])
    p.add_argument("--weights", type=Path, help="neural checkpoint (default: the shipped weights)")
    p.add_argument("--out", type=Path, default=Path("out/ld_eval"))
    p.add_argument("--limit", type=int)
    p.set_defaults(func=_eval)

    p = sub.add_parser("export-onnx", help="export LaneNet to an ONNX file: the whole detector (frame in, lines "
                                           "out), which detector neural-onnx runs without torch or OpenCV "
                                           "(detector.weights = the file)")
    p.add_argument("--weights", type=Path, help="checkpoint (default: the shipped weights)")
    p.add_argument("--out", type=Path, default=Path("lanenet.onnx"))
    p.add_argument("--network-only", action="store_true",
                   help="export only the network (preprocessed input in, column and existence logits out)")
    p.add_argument("--fit", choices=("cubic", "near", "spread"), default="cubic",
                   help="the anchor fit inside the detector graph (detector.fit; default cubic; spread is solved per "
                        "frame and cannot be baked into a graph)")
    p.set_defaults(func=_export_onnx)

    from testbed.perception.detectors.registry import DETECTORS
    from testbed.perception.lab.traffic_drive import LEAD_GAP_M

    p = sub.add_parser("closed-loop", help="drive held-out tracks of every preset in every condition and table "
                                           "|D_LD - phys_dev| with and without lane tracking")
    p.add_argument("--detector", default="neural", choices=DETECTORS.names())
    p.add_argument("--presets", nargs="+", metavar="PRESET", help="track presets (default: all)")
    p.add_argument("--conditions", nargs="+", metavar="CONDITION", help="camera conditions (default: all)")
    p.add_argument("--duration", type=float, default=30.0, help="simulated seconds per drive")
    p.add_argument("--workers", type=int, default=1, help="drives run at once, each in its own process")
    p.add_argument("--traffic", type=_cars, default=0, metavar="N",
                   help="N traffic cars at the ego's speed, the first of the ego lane --lead-gap ahead, hiding the "
                        "far part of the ego lines; the tables split the ticks by occlusion (default 0: none)")
    p.add_argument("--lead-gap", type=float, default=None, metavar="M",
                   help=f"ego front to lead car rear with --traffic (m; default {LEAD_GAP_M:g})")
    p.add_argument("--layouts", choices=("cells", "check"), default="cells",
                   help="held-out track layouts driven: the cells' (default), or the check block's, a second layout "
                        "per preset × condition for checking what was tuned on the first")
    p.add_argument("--weights", metavar="CHECKPOINT",
                   help="the neural detector's checkpoint (detector.weights: a path, or a shipped one by name; "
                        "default: the shipped lanenet.pt, with and without --traffic)")
    p.add_argument("--fit", choices=("cubic", "near", "spread"),
                   help="the neural detector's anchor fit (detector.fit; default: the detector's own)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override every drive's scenario as `ld3 run --set` does (repeatable), e.g. "
                        "'detector.track_at=[]' for the tracker fed the lines' coefficients")
    p.add_argument("--out", type=Path, default=Path("out/ld_closed_loop"))
    p.set_defaults(func=_closed_loop)
    return ld


def _cars(text: str) -> int:
    """A number of traffic cars (0 = none), for argparse."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of cars, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be a number of cars >= 0, got {n}")
    return n


def at_least(value: float | None, low: float, flag: str) -> None:
    """A UserError naming `flag` unless `value` (when given) is a finite number >= `low`."""
    import math

    from testbed.errors import UserError

    if value is not None and not (math.isfinite(value) and value >= low):
        raise UserError(f"{flag} must be a finite number >= {low:g}, got {value}")


def _dataset(args: argparse.Namespace) -> int:
    from testbed.eval.run.folder import output_folder
    from testbed.perception.training.dataset import build_dataset

    for flag, value, low in (("--frames", args.frames, 1), ("--seed", args.seed, 0),
                             ("--frames-per-episode", args.frames_per_episode, 1), ("--workers", args.workers, 1),
                             ("--label-draws", args.label_draws, 0)):
        at_least(value, low, flag)
    with output_folder(args.out, marker="dataset.json", what="a dataset", can_force=False) as tmp:
        n = build_dataset(tmp, args.frames, args.split, args.seed, args.frames_per_episode,
                      workers=args.workers, progress=True, conditions=args.conditions, label_draws=args.label_draws,
                      traffic=args.traffic, presets=args.presets, tracks=args.tracks)
    print(f"wrote {n} {args.split} frames to {args.out}")
    return 0


def _train(args: argparse.Namespace) -> int:
    from testbed.eval.run.folder import output_folder
    from testbed.perception.training.train import TrainConfig, train

    for flag, value, low in (("--epochs", args.epochs, 1), ("--threads", args.threads, 1), ("--limit", args.limit, 1),
                             ("--negatives", args.negatives, 0)):
        at_least(value, low, flag)
    for flag, value in (("--lr", args.lr), ("--minutes", args.minutes)):
        at_least(value, 1e-12, flag)
    cfg = TrainConfig(epochs=args.epochs, threads=args.threads, max_minutes=args.minutes, lr=args.lr,
                      input_rows=args.input_rows, negatives=args.negatives, freeze_bn=args.freeze_bn)
    with output_folder(args.out, True, "lanenet.pt", "a training run") as tmp:
        res = train(args.data, tmp, cfg, val_dir=args.val, limit=args.limit, progress=True, init=args.init)
    print(f"checkpoint {args.out / res.checkpoint.name}, curve {args.out / res.curve.name}")
    if res.history:
        print({k: round(v, 4) if isinstance(v, float) else v for k, v in res.history[-1].items()})
    return 0


def _average(args: argparse.Namespace) -> int:
    from testbed.eval.run.folder import output_file
    from testbed.perception.training.weight_mean import mean_checkpoint

    with output_file(args.out, ".pt") as tmp:
        mean_checkpoint(args.checkpoints, tmp)
    print(f"wrote {args.out}")
    return 0


def _existence_refit(args: argparse.Namespace) -> int:
    from testbed.perception.training.existence_head import write_refit

    if args.negatives < 1:
        from testbed.errors import UserError

        raise UserError("--negatives must be at least 1")
    fit = write_refit(args.init, args.data, args.out, args.negatives, args.seed)
    print(f"wrote {args.out}: {fit['positives']} positives, existence right on {fit['positive_accuracy']:.1%} of "
          f"their lines; {fit['negatives']} negatives, both lines rejected on {fit['negatives_rejected']:.1%}")
    return 0


def _eval(args: argparse.Namespace) -> int:
    from testbed.eval.run.folder import check_out_dir, output_folder
    from testbed.perception.detectors.classical import ClassicalLaneDetector
    from testbed.perception.detectors.neural import NeuralLaneDetector, load_model
    from testbed.perception.training.dataset import load_frames
    from testbed.perception.training.evaluate import evaluate, markdown_table, write_report
    from vehicles.camera_rig import CameraRig
    from vehicles.params import get_vehicle

    at_least(args.limit, 1, "--limit")
    if args.data is None:
        from testbed.errors import UserError

        raise UserError("ld eval needs --data DIR (a held-out dataset) or --labels FORMAT:PATH")
    check_out_dir(args.out, True, "ld_eval.json", "a lane-detector evaluation")
    rig = CameraRig(get_vehicle("sedan").camera)
    frames = load_frames(args.data, args.limit)
    reports, grid = [], None
    for name in args.detector:
        det = NeuralLaneDetector(load_model(args.weights)) if name == "neural" else ClassicalLaneDetector(rig)
        rep, dets = evaluate(det, frames, progress=True)
        reports.append(rep)
        if grid is None:
            grid = (frames, dets, rig)
    with output_folder(args.out, True, "ld_eval.json", "a lane-detector evaluation") as tmp:
        paths = write_report(reports, grid, tmp)
    print(markdown_table(reports))
    print(", ".join(str(args.out / p.name) for p in paths.values()))
    return 0


def _export_onnx(args: argparse.Namespace) -> int:
    from testbed.errors import UserError
    from testbed.eval.run.folder import output_file
    from testbed.perception.detectors.neural import load_model
    from testbed.perception.detectors.onnx_runtime import export_onnx
    from testbed.perception.training.onnx_detector_graph import export_detector_onnx

    if args.network_only and args.fit != "cubic":
        raise UserError("--network-only exports no anchor fit: drop --fit")
    with output_file(args.out, ".onnx") as tmp:
        model = load_model(args.weights)
        data = export_onnx(model, tmp) if args.network_only else export_detector_onnx(model, tmp, args.fit)
    print(f"wrote {args.out} ({len(data) / 1024:.0f} KiB)")
    return 0


def _closed_loop(args: argparse.Namespace) -> int:
    from testbed.conditions import CONDITIONS
    from testbed.errors import UserError
    from testbed.eval.run.folder import check_out_dir, output_folder
    from testbed.perception.lab.closed_loop import markdown_table, run_closed_loop, write_report
    from tracks.presets import PRESETS

    if args.detector == "none":
        raise UserError("closed-loop needs a lane detector: --detector neural, classical or oracle")
    check_out_dir(args.out, True, "closed_loop.csv", "a closed-loop report")
    results = run_closed_loop(args.presets or list(PRESETS), args.conditions or list(CONDITIONS), args.detector,
                              args.duration, workers=args.workers, progress=True, traffic=args.traffic,
                              lead_gap=args.lead_gap, weights=args.weights, check=args.layouts == "check",
                              fit=args.fit, settings=tuple(args.set))
    with output_folder(args.out, True, "closed_loop.csv", "a closed-loop report") as tmp:
        paths = {k: args.out / p.name for k, p in write_report(results, tmp).items()}
    print(markdown_table(results))
    print(", ".join(str(p) for p in paths.values()))
    return 0
