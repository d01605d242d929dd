"""The element-wise mean of LaneNet checkpoints of one shape (a weight average, "model soup"): every
floating-point tensor of the state dicts averaged, batch-norm running statistics included; integer tensors
(batch counts) and the shape fields taken from the first checkpoint; the history names the averaged files."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import torch

from testbed.errors import UserError
from testbed.perception.detectors.neural import model_from_checkpoint, read_checkpoint


def mean_checkpoint(paths: Sequence[Path], out: Path) -> Path:
    """Write the mean of the checkpoints at `paths` (at least two, one network shape) to `out`; a missing,
    unreadable or mismatched checkpoint is a UserError naming it, before anything is written."""
    if len(paths) < 2:
        raise UserError(f"averaging needs at least two checkpoints, got {len(paths)}")
    loaded = [read_checkpoint(path) for path in paths]
    for path, ckpt in zip(paths, loaded, strict=True):
        model_from_checkpoint(ckpt, path)
    first = loaded[0]
    shape = _shape(first)
    for path, ckpt in zip(paths, loaded, strict=True):
        if _shape(ckpt) != shape:
            raise UserError(f"{path} has another network shape than {paths[0]}: average checkpoints of one shape")
    state = {k: (torch.stack([c["state_dict"][k] for c in loaded]).mean(dim=0) if v.is_floating_point()
                 else v.clone()) for k, v in first["state_dict"].items()}
    history = json.dumps({"mean_of": [str(p) for p in paths]})
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({**first, "state_dict": state, "history": history}, out)
    return out


def _shape(ckpt: dict) -> tuple:
    """A checkpoint's network shape: its width, input rows and every tensor's name and size."""
    return (ckpt.get("width"), ckpt.get("input_rows"),
            {name: tuple(tensor.shape) for name, tensor in ckpt["state_dict"].items()})
