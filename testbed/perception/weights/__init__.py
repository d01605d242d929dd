"""Shipped LaneNet weights (lanenet.pt), loaded by `testbed.perception.neural.load_model`.

Provenance (two stages). First `ld3 ld train` with its defaults (27-minute budget, 2 threads; 24 epochs) from
scratch at commit 697b3a6 on D/train, D/train2, D/train3. Then, at commit d469bd8, 45 more minutes from those
weights on all four sets at a lower peak learning rate (30 epochs of 54k frames), labelled with visible-paint
existence (`labels.PaintVisibility`):
    ld3 ld dataset --out D/train  --frames 20000 --split train --seed 1 --frames-per-episode 30 --workers 2
    ld3 ld dataset --out D/train2 --frames 8000  --split train --seed 2 --frames-per-episode 20 --workers 2
    ld3 ld dataset --out D/train3 --frames 12000 --split train --seed 3 --frames-per-episode 20 --workers 2
    ld3 ld dataset --out D/train4 --frames 13960 --split train --seed 4 --frames-per-episode 20 --workers 2
    ld3 ld train --data D/train D/train2 D/train3 --val D/heldout --out runs/ld-train
    ld3 ld train --data D/train D/train2 D/train3 D/train4 --val D/heldout --out runs/ld-train-v5ft \
        --init runs/ld-train/lanenet.pt --epochs 200 --minutes 45 --lr 1e-3
Held-out sets: `ld3 ld dataset --out D/heldout --frames 1440 --split heldout --seed 0 --frames-per-episode 20`
and D/heldout-big (`--frames 4800 --seed 5`). Held-out mean |D_LD error| 0.058 / 0.059 m on the two sets;
today's default training from scratch (27 minutes, 30 epochs, D/train..train3) reaches 0.061 / 0.066 m.
"""
