"""The shipped LaneNet weights (lanenet.pt), read by every run with a neural detector that names no other
checkpoint, with and without traffic; loaded by `testbed.perception.detectors.neural.load_model`.

Provenance: `ld3 ld train` from scratch with the shipped recipe (56-row input, lr 3e-3, batch 64, 30 epochs, all
ran in 44.8 min on 2 threads) on the union of fourteen training sets, 23,100 frames, and 1,200 frames without
lines (`--negatives`), then the element-wise mean of epochs 22 and 24. The sets (`ld3 ld dataset --split train
--workers 1`; all but the first two with `--frames-per-episode 10`):
    --seed 0 --frames 2400                      --seed 1 --frames 1200 --traffic 3
    --seed 11 --traffic 6 --frames 2000         --seed 13 --traffic 6 --conditions worn night --frames 2000
    --seed 14 --traffic 6 --conditions worn --frames 3000
    --seed 17 --traffic 6 --presets slr --conditions worn --frames 600
    --seed 19 --traffic 6 --presets urban-curvy --conditions rain --frames 600
    --seed 21 --traffic 6 --presets highway urban-curvy --conditions night rain --frames 1000
    --seed 22 --traffic 6 --conditions night rain --frames 2000
    --seed 23 --traffic 6 --presets highway urban-curvy --conditions night rain --frames 2000
    --seed 25 --traffic 6 --presets highway --conditions night --frames 1500
    --seed 26 --traffic 6 --presets highway --conditions worn --frames 1500
    --seed 27 --tracks xodr:FILE... --frames 2500   (12 public OpenDRIVE files, docs/decisions.md)
    --seed 28 --presets slr --conditions worn --frames 800
    ld3 ld train --data <the 14 sets> --val D/heldout --out A --input-rows 56 --negatives 1200 --epochs 30 \
        --minutes 48 --threads 2 --lr 3e-3     (every epoch's checkpoint kept: A/ep22.pt, A/ep24.pt)
    ld3 ld average --out lanenet.pt A/ep22.pt A/ep24.pt
Held-out set: `ld3 ld dataset --out D/heldout --frames 600 --split heldout --seed 0`. Measured in
docs/decisions.md (lane detector, one checkpoint for every run).
"""

from importlib import resources
from pathlib import Path

SHIPPED = ("lanenet.pt",)
"""Checkpoints in this package, named by file name in `detector.weights`."""


def resolve(value: str) -> Path:
    """The checkpoint `value` names: a shipped one by its file name (`SHIPPED`), otherwise a path."""
    if value in SHIPPED:
        return Path(str(resources.files(__name__) / value))
    return Path(value).expanduser()
