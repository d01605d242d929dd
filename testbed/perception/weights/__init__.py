"""Shipped LaneNet weights (lanenet.pt), loaded by `testbed.perception.neural.load_model`.

Provenance: `ld3 ld train` with its defaults (27-minute budget, 2 threads; 24 epochs here) from scratch at commit
697b3a6 (before training moved to channels-last; the same command now runs all 30 epochs, held-out mean 0.061 m
against these weights' 0.0608 m) on three training sets, labelled with visible-paint existence
(`labels.PaintVisibility`):
    ld3 ld dataset --out D/train  --frames 20000 --split train --seed 1 --frames-per-episode 30 --workers 2
    ld3 ld dataset --out D/train2 --frames 8000  --split train --seed 2 --frames-per-episode 20 --workers 2
    ld3 ld dataset --out D/train3 --frames 12000 --split train --seed 3 --frames-per-episode 20 --workers 2
    ld3 ld train --data D/train D/train2 D/train3 --val D/heldout --out runs/ld-train
Held-out set: `ld3 ld dataset --out D/heldout --frames 1440 --split heldout --seed 0 --frames-per-episode 20`.
"""
