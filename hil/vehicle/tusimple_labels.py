"""Labelled frames in the TuSimple benchmark's format, for `ld3 ld eval --labels tusimple:PATH`: one JSON object a
line (`raw_file`, the picture, relative to the label file's folder; `h_samples`, the labelled rows; `lanes`, each
lane's x at those rows, -2 where it has no point). What cannot be read is refused in one line."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from testbed.errors import UserError

FORMATS = ("tusimple",)
MAX_PIXEL = 1e5
"""Largest label coordinate read (px)."""


@dataclass(frozen=True)
class LabelledFrame:
    """One labelled frame: its picture, the label's rows (px) and each labelled lane's x there (`ABSENT`: none)."""

    raw_file: str
    image: Path
    rows: np.ndarray
    lanes: tuple[np.ndarray, ...]


def parse_labels(spec: str) -> tuple[str, Path]:
    """`FORMAT:PATH` -> (format, path); a one-line UserError for anything else."""
    kind, sep, path = spec.partition(":")
    if not sep or not path:
        raise UserError(f"--labels takes FORMAT:PATH (FORMAT: {', '.join(FORMATS)}), got {spec!r}")
    if kind not in FORMATS:
        raise UserError(f"--labels: unknown label format {kind!r}: {', '.join(FORMATS)}")
    return kind, Path(path)


def read_tusimple(path: Path) -> list[LabelledFrame]:
    """The frames of a TuSimple label file (one JSON object a line: raw_file, h_samples, lanes; raw_file relative to
    the file's folder), or of every `*.json` in a folder; a one-line UserError for what cannot be read."""
    files = sorted(path.glob("*.json")) if path.is_dir() else [path]
    if not files:
        raise UserError(f"--labels {path}: no *.json label file in that folder")
    frames = []
    for file in files:
        try:
            lines = file.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            raise UserError(f"--labels {file}: {exc}") from None
        for n, line in enumerate(lines, 1):
            if line.strip():
                frames.append(_tusimple_frame(file, n, line))
    if not frames:
        raise UserError(f"--labels {path}: no labelled frame")
    return frames


def _tusimple_frame(file: Path, n: int, line: str) -> LabelledFrame:
    where = f"--labels {file} line {n}"
    try:
        entry = json.loads(line)
        raw_file, rows = str(entry["raw_file"]), np.array(entry["h_samples"], dtype=float)
        lanes = tuple(np.array(lane, dtype=float) for lane in entry["lanes"])
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise UserError(f"{where}: not a TuSimple label ({type(exc).__name__}: {exc})") from None
    if rows.ndim != 1 or any(lane.shape != rows.shape for lane in lanes):
        raise UserError(f"{where}: every lane needs one x per h_samples row")
    if any(not (np.isfinite(a).all() and (np.abs(a) < MAX_PIXEL).all()) for a in (rows, *lanes)):
        raise UserError(f"{where}: h_samples and lanes must be pixel coordinates (finite, under {MAX_PIXEL:g})")
    image = file.parent / raw_file
    if not image.is_file():
        raise UserError(f"{where}: the frame {image} does not exist")
    return LabelledFrame(raw_file, image, rows, lanes)
