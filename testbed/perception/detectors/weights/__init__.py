"""Shipped LaneNet weights (lanenet.pt), loaded by `testbed.perception.detectors.neural.load_model`.

Provenance: `ld3 ld train` with its defaults (27-minute budget, 2 threads; all 30 epochs ran, 18.3 minutes) from
scratch on four training sets rendered with the strip-warped ground canvas and labelled with the existence
seen in each rendered frame (`labels.FrameVisibility`, VISIBLE_FRACTION 0.15), the fourth in the night and worn
conditions only:
    ld3 ld dataset --out D/train  --frames 20000 --split train --seed 1 --frames-per-episode 30 --workers 2
    ld3 ld dataset --out D/train2 --frames 8000  --split train --seed 2 --frames-per-episode 20 --workers 2
    ld3 ld dataset --out D/train3 --frames 12000 --split train --seed 3 --frames-per-episode 20 --workers 2
    ld3 ld dataset --out D/train4 --frames 8000  --split train --seed 4 --frames-per-episode 20 --conditions night worn
    ld3 ld train --data D/train D/train2 D/train3 D/train4 --val D/heldout --out runs/ld-train
Held-out set: `ld3 ld dataset --out D/heldout --frames 1440 --split heldout --seed 0 --frames-per-episode 20`.

`lanenet-traffic.pt` is those weights fine-tuned in three steps on frames with up to 6 cars (a lead car
hiding the far lines) and frames without traffic; a run with traffic reads it unless `detector.weights` names
other weights. First step (renders stopped at 2,520 and 1,170 frames):
    ld3 ld dataset --out D/traffic --split train --seed 11 --frames-per-episode 10 --traffic 6 --frames ...
    ld3 ld dataset --out D/plain --split train --seed 12 --frames ...
    ld3 ld train --init lanenet.pt --data D/traffic D/plain --epochs 12 --minutes 10 --lr 1e-3 --out T1
Second step, from T1/lanenet.pt, on two more sets with traffic in the worn and night conditions, then the
element-wise mean of two runs' state dicts (a and b differ in learning rate and epochs only):
    ld3 ld dataset --out D/worn-night --split train --seed 13 --frames-per-episode 10 --traffic 6 \
        --conditions worn night --frames 2000
    ld3 ld dataset --out D/worn --split train --seed 14 --frames-per-episode 10 --traffic 6 \
        --conditions worn --frames 3000
    ld3 ld train --init T1/lanenet.pt --data D/traffic D/worn-night D/worn D/plain --threads 1 --epochs 20 \
        --minutes 25 --lr 5e-4 --out a
    ld3 ld train --init T1/lanenet.pt --data D/traffic D/worn-night D/worn D/plain --threads 1 --epochs 30 \
        --minutes 25 --lr 1e-3 --out b
    ld3 ld average --out T2.pt a/lanenet.pt b/lanenet.pt
Third step, from T2.pt, on single-lane roads with worn lines (with and without traffic) and urban-curvy in rain
with traffic, then the mean with T2.pt:
    ld3 ld dataset --out D/slr-worn-traffic --split train --seed 17 --frames-per-episode 10 --traffic 6 \
        --presets slr --conditions worn --frames 1500
    ld3 ld dataset --out D/slr-worn --split train --seed 18 --frames-per-episode 10 --presets slr \
        --conditions worn --frames 1000
    ld3 ld dataset --out D/curvy-rain-traffic --split train --seed 19 --frames-per-episode 10 --traffic 6 \
        --presets urban-curvy --conditions rain --frames 800
    ld3 ld train --init T2.pt --data D/traffic D/worn-night D/worn D/plain D/slr-worn-traffic D/slr-worn \
        D/curvy-rain-traffic --threads 1 --epochs 12 --minutes 25 --lr 5e-4 --out d
    ld3 ld average --out lanenet-traffic.pt d/lanenet.pt T2.pt
"""

from importlib import resources
from pathlib import Path

SHIPPED = ("lanenet.pt", "lanenet-traffic.pt")
"""Checkpoints in this package, named by file name in `detector.weights`."""


def resolve(value: str) -> Path:
    """The checkpoint `value` names: a shipped one by its file name (`SHIPPED`), otherwise a path."""
    if value in SHIPPED:
        return Path(str(resources.files(__name__) / value))
    return Path(value).expanduser()
