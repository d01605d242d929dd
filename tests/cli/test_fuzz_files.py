"""Hostile files per format, made by seeded mutations of a valid file (bits flipped, the file cut short, bytes
inserted, a number swapped for a hostile one: 1e300, -1, 0, nan, 99999), each given to the command that reads
that format in a subprocess bounded in time (60 s) and address space (2 GiB). Whatever the mutant, the command
ends in a correct run (exit 0) or a refusal in one line (exit 2, or 4 for a CAN link), never an internal error,
a traceback, a hang, or a write outside its --out. Two mutants per format by default; `-m slow` runs twenty."""

from __future__ import annotations

import io
import json
import os
import re
import resource
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from tests.cli.hostile_inputs import ASC_HEAD, PROFILE, xodr
from tests.eval.run.summary_helpers import fake_summary

ROOT = Path(__file__).resolve().parents[2]
TIME_LIMIT_S = 60
MEMORY_LIMIT = 2 << 30
HOSTILE_NUMBERS = (b"1e300", b"-1", b"0", b"nan", b"99999", b"-1e308", b"1e-320")
NUMBER = re.compile(rb"-?\d+(\.\d+)?(e-?\d+)?")
GOOD_TOML = 'track = "slr"\nduration = 1.0\nspeed = 5.0\nseed = 3\n'


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    """`data` changed in one of four ways, chosen and placed by `rng`."""
    how = int(rng.integers(4))
    if how == 0 and data:
        buf = bytearray(data)
        for i in rng.integers(len(buf), size=int(rng.integers(1, 9))):
            buf[i] ^= 1 << int(rng.integers(8))
        return bytes(buf)
    if how == 1:
        return data[:int(rng.integers(len(data) + 1))]
    if how == 2:
        at = int(rng.integers(len(data) + 1))
        return data[:at] + rng.integers(256, size=int(rng.integers(1, 64))).astype(np.uint8).tobytes() + data[at:]
    numbers = list(NUMBER.finditer(data))
    if not numbers:
        return data + b"\x00"
    m = numbers[int(rng.integers(len(numbers)))]
    return data[:m.start()] + HOSTILE_NUMBERS[int(rng.integers(len(HOSTILE_NUMBERS)))] + data[m.end():]


def _checkpoint() -> bytes:
    import torch

    from testbed.perception.detectors.neural import LaneNet

    buf = io.BytesIO()
    torch.save({"state_dict": LaneNet(8).state_dict(), "width": 8, "input_rows": 56}, buf)
    return buf.getvalue()


def _shard() -> bytes:
    frames = 2
    buf = io.BytesIO()
    np.savez(buf, images=np.full((frames, 160, 320, 3), 90, np.uint8),
             meta=np.asarray(['{"preset": "slr", "condition": "day"}'] * frames),
             left=np.tile([1.7, 0.0, 0.0, 0.0], (frames, 1)), right=np.tile([-1.7, 0.0, 0.0, 0.0], (frames, 1)),
             left_exists=np.ones(frames, bool), right_exists=np.ones(frames, bool),
             lane_width=np.full(frames, 3.4), deviation=np.zeros(frames))
    return buf.getvalue()


def _can_log() -> bytes:
    lines = [f" {0.02 * i:.6f} 1  130             Tx   d 8 0{i % 10} 04 00 00 00 00 0{i % 10} 04" for i in range(20)]
    return (ASC_HEAD + "\n".join(lines) + "\nEnd TriggerBlock\n").encode()


def _grey_png() -> bytes:
    import cv2

    return cv2.imencode(".png", np.full((36, 64, 3), 90, np.uint8))[1].tobytes()


TUSIMPLE_LABEL = (b'{"raw_file": "f.png", "h_samples": [20, 25, 30, 35], "lanes": [[30, 26, 22, 18], [-2, 36, 40, 44]]}'
                  b'\n')
CALIBRATION = (b"[intrinsics]\nwidth = 640\nheight = 360\nfx = 500\nfy = 500\ncx = 320\ncy = 180\n[extrinsics]\n"
               b"mount_x = 0\nmount_height = 1.2\npitch_deg = 0\n")
SUMMARY = json.dumps(fake_summary(scenario="x", defense="none", max_abs_dev_m=0.1).model_dump(mode="json"),
                     indent=2).encode()
TRAJECTORY = b"t,phys_dev\n" + b"".join(f"{0.025 * i:.3f},{0.01 * i:.4f}\n".encode() for i in range(40))


@dataclass(frozen=True)
class Format:
    """A file format: the valid file, where the mutant goes, the files beside it, and the argv that reads it."""

    name: str
    valid: Callable[[], bytes]
    path: str
    argv: tuple[str, ...]
    beside: tuple[tuple[str, bytes], ...] = ()


FORMATS = [
    Format("opendrive", lambda: xodr().encode(), "r.xodr", ("tracks", "routes", "xodr:{ws}/r.xodr")),
    Format("profile-dbc", lambda: (PROFILE / "chassis.dbc").read_bytes(), "p/chassis.dbc",
           ("ecu", "--profile", "{ws}/p", "--duration", "0.2"), (("p/profile.toml", (PROFILE / "profile.toml")
                                                                 .read_bytes()),)),
    Format("profile-toml", lambda: (PROFILE / "profile.toml").read_bytes(), "p/profile.toml",
           ("ecu", "--profile", "{ws}/p", "--duration", "0.2"), (("p/chassis.dbc", (PROFILE / "chassis.dbc")
                                                                 .read_bytes()),)),
    Format("checkpoint", _checkpoint, "w.pt", ("ld", "export-onnx", "--weights", "{ws}/w.pt", "--network-only",
                                               "--out", "{ws}/out.onnx")),
    Format("can-log", _can_log, "c.asc", ("hil", "replay", "{ws}/c.asc")),
    Format("dataset", _shard, "d/shard_00000.npz", ("ld", "eval", "--data", "{ws}/d", "--detector", "classical",
                                                    "--out", "{ws}/out")),
    Format("tusimple-labels", lambda: TUSIMPLE_LABEL, "l.json",
           ("ld", "eval", "--labels", "tusimple:{ws}/l.json", "--calibration", "{ws}/c.toml", "--detector",
            "classical", "--out", "{ws}/out"), (("f.png", _grey_png()), ("c.toml", CALIBRATION))),
    Format("trajectory-csv", lambda: TRAJECTORY, "run/trajectory.csv", ("compare", "{ws}/run", "--out", "{ws}/out"),
           (("run/summary.json", SUMMARY),)),
    Format("summary-json", lambda: SUMMARY, "run/summary.json", ("compare", "{ws}/run", "--out", "{ws}/out"),
           (("run/trajectory.csv", TRAJECTORY),)),
    Format("trace-csv", lambda: b"t,dev\n0,0\n1,0.5\n2,1.0\n", "t.csv",
           ("run", "slr", "--duration", "1", "--localization", "msf", "--attack", "trace:trace={ws}/t.csv,start=0",
            "--out", "{ws}/out")),
    Format("scenario-toml", lambda: GOOD_TOML.encode(), "s.toml", ("run", "{ws}/s.toml", "--out", "{ws}/out")),
]


def _limits() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def run_mutant(fmt: Format, seed: int, tmp: Path) -> tuple[int, list[str], set[str]]:
    """Exit status, stderr lines and paths written outside `ws/out` of `fmt`'s command on mutant `seed`."""
    ws, cwd = tmp / "ws", tmp / "cwd"
    cwd.mkdir()
    for name, data in ((fmt.path, mutate(fmt.valid(), np.random.default_rng(seed))), *fmt.beside):
        (ws / name).parent.mkdir(parents=True, exist_ok=True)
        (ws / name).write_bytes(data)
    before = _files(tmp)
    argv = [a.replace("{ws}", str(ws)) for a in fmt.argv]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    try:
        done = subprocess.run([sys.executable, "-m", "testbed.cli", *argv], cwd=cwd, env=env, capture_output=True,
                              text=True, timeout=TIME_LIMIT_S, preexec_fn=_limits, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{fmt.name} mutant {seed}: no answer within {TIME_LIMIT_S} s")
    lines = [line for line in done.stderr.splitlines()
             if line.strip() and not line.startswith("pybullet build time") and "\r" not in line]
    outside = {p for p in _files(tmp) - before if not p.startswith("ws/out")}
    return done.returncode, lines, outside


QUICK, SLOW = 2, 20
CASES = [*((fmt, seed) for fmt in FORMATS for seed in range(QUICK)),
         *(pytest.param(fmt, seed, marks=pytest.mark.slow) for fmt in FORMATS for seed in range(QUICK, SLOW))]


@pytest.mark.parametrize(("fmt", "seed"), CASES, ids=lambda v: v.name if isinstance(v, Format) else str(v))
def test_a_mutated_file_runs_or_is_refused_in_one_line(fmt, seed, tmp_path):
    code, lines, outside = run_mutant(fmt, seed, tmp_path)
    assert code in (0, 2, 4), (code, lines[-5:])
    assert not any("Traceback" in line or "internal error" in line for line in lines), lines[-5:]
    if code != 0:
        assert len(lines) == 1, lines
    assert not outside, outside


def test_mutations_change_the_file_and_repeat_by_seed():
    data = xodr().encode()
    mutants = [mutate(data, np.random.default_rng(seed)) for seed in range(8)]
    assert all(m != data for m in mutants)
    assert mutants == [mutate(data, np.random.default_rng(seed)) for seed in range(8)]
