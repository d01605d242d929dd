"""Hostile files and values for the table (`tests/cli/bad_inputs.py`): per file format a valid file made bad in
one way (OpenDRIVE, chassis profile, checkpoint, ONNX, MCAP, CAN log, dataset, run folder, NMEA, trace CSV,
scenario TOML), and values no command may take (infinite time-outs, NaN limits, zero epochs)."""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from pathlib import Path

from tests.cli.case import Case
from tests.eval.run.summary_helpers import fake_summary

PROFILE = Path(__file__).resolve().parents[2] / "hil" / "link" / "profiles" / "ld3-dev"
GOOD = 'track = "slr"\nduration = 2.0\n'

XODR = """<?xml version='1.0' encoding='utf-8'?>
<OpenDRIVE><header revMajor="1" revMinor="7" name="h"/>
<road name="r" length="{length}" id="1" junction="-1" rule="RHT"><link/>
<planView>{geometry}</planView>
<lanes><laneOffset s="0.0" a="1.78" b="0.0" c="0.0" d="0.0"/><laneSection s="0.0">
<center><lane id="0" type="none"><roadMark sOffset="0.0" type="solid"/></lane></center>
<right><lane id="-1" type="driving"><width sOffset="0.0" a="{width}" b="0.0" c="0.0" d="{d}"/>
<roadMark sOffset="0.0" type="solid"/></lane></right>
</laneSection></lanes></road></OpenDRIVE>
"""
LINE = '<geometry s="0.0" x="{x}" y="0.0" hdg="0.0" length="{length}"><line/></geometry>'


def xodr(length: float | str = 200.0, width: float | str = 3.5, d: float | str = 0.0, geometry: str | None = None,
         x: float | str = 0.0) -> str:
    """A one-road OpenDRIVE file (one driving lane), one value changed."""
    geometry = LINE.format(x=x, length=length) if geometry is None else geometry
    return XODR.format(length=length, width=width, d=d, geometry=geometry)


def _xodr(id: str, says: str, **change: float | str) -> Case:
    return Case(f"xodr-{id}", ("tracks", "show", "xodr:{ws}/r.xodr", "--out", "{ws}/t.png"), says,
                {"r.xodr": xodr(**change)})


def _geometry(id: str, says: str, length: float, shape: str, extra: str = "") -> Case:
    geometry = f'<geometry s="0.0" x="0" y="0" hdg="0" length="{length}">{shape}</geometry>{extra}'
    return Case(f"xodr-{id}", ("tracks", "show", "xodr:{ws}/r.xodr", "--out", "{ws}/t.png"), says,
                {"r.xodr": xodr(length=length, geometry=geometry)})


OPENDRIVE = [
    _xodr("negative-length", "length", length=-5),
    _xodr("far-coordinates", "coordinate", x=1e300),
    _xodr("negative-width", "width", width=-3.5),
    _xodr("zero-width", "width", width=0.0),
    _xodr("huge-poly3-width", "width", d=1e12),
    _xodr("huge-road", "longer than", length=1e9),
    _geometry("degenerate-parampoly3", "paramPoly3", 100.0,
              '<paramPoly3 aU="0" bU="0" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0" pRange="normalized"/>'),
    _geometry("huge-poly3", "poly3", 100.0, '<poly3 a="0" b="0" c="0" d="1e30"/>'),
    _geometry("arc-wraps", "turns", 1800.0, '<arc curvature="0.01"/>'),
    _geometry("overlap", "overlap", 100.0, "<line/>",
              '<geometry s="0.0" x="0" y="50" hdg="0" length="100"><line/></geometry>'),
]


def _profile(id: str, says: str, dbc: str | None = None, toml: str | None = None) -> Case:
    files: dict[str, str | bytes] = {
        "prof/chassis.dbc": dbc if dbc is not None else (PROFILE / "chassis.dbc").read_text(),
        "prof/profile.toml": toml if toml is not None else (PROFILE / "profile.toml").read_text()}
    return Case(f"profile-{id}", ("hil", "parking-lot", "--profile", "{ws}/prof", "--duration", "2",
                                  "--out", "{ws}/h"), says, files)


def _dbc(old: str, new: str) -> str:
    text = (PROFILE / "chassis.dbc").read_text()
    assert old in text, old
    return text.replace(old, new, 1)


def _toml_of_profile(old: str, new: str) -> str:
    text = (PROFILE / "profile.toml").read_text()
    assert old in text, old
    return text.replace(old, new, 1)


PROFILES = [
    _profile("duplicate-frame-id", "305", dbc=_dbc("BO_ 306 ACU_SteerCtrl", "BO_ 305 ACU_SteerCtrl")),
    _profile("scale-zero", "scale", dbc=_dbc("SteerAngleTarget : 8|16@1- (0.002,0)",
                                             "SteerAngleTarget : 8|16@1- (0,0)")),
    _profile("gear-huge", "drive", toml=_toml_of_profile("drive = 4", "drive = 99999")),
    _profile("dbc-garbage", "chassis.dbc", dbc="BO_ ][ \x00\x01 garbage"),
    _profile("dbc-escape", "chassis.dbc", dbc="\x1b[2J\x1b[31mBO_ x"),
    _profile("frame-huge", "99999 bytes", dbc=_dbc("BO_ 1345 SIM_TruthMotion: 8 VCU",
                                                   "BO_ 1345 SIM_TruthMotion: 99999 VCU")),
    _profile("frame-long", "60 bytes", dbc=_dbc("BO_ 1345 SIM_TruthMotion: 8 VCU", "BO_ 1345 SIM_TruthMotion: 60 VCU")),
    Case("profile-symlink-loop", ("hil", "parking-lot", "--profile", "{ws}/loop", "--duration", "2", "--out",
                                  "{ws}/h"), "loop", links={"loop": "loop"}),
]


def _checkpoint(state: dict) -> bytes:
    import torch

    buf = io.BytesIO()
    torch.save(state, buf)
    return buf.getvalue()


def _wrong_shape() -> bytes:
    import torch

    from testbed.perception.detectors.neural import LaneNet

    state = {k: torch.zeros([s + 1 for s in v.shape]) for k, v in LaneNet(16).state_dict().items()}
    return _checkpoint({"state_dict": state, "width": 16})


def _wrong_width() -> bytes:
    from testbed.perception.detectors.neural import LaneNet

    return _checkpoint({"state_dict": LaneNet(16).state_dict(), "width": 32})


def _run_weights(id: str, says: str, name: str, content: bytes | Callable[[], bytes], detector: str = "neural") -> Case:
    return Case(f"weights-{id}", ("run", "highway", "--detector", detector, "--duration", "2", "--set",
                                  f"detector.weights={{ws}}/{name}", "--out", "{ws}/r"), says, {name: content})


CHECKPOINTS = [
    _run_weights("wrong-shape", "w.pt", "w.pt", _wrong_shape),
    _run_weights("empty", "w.pt", "w.pt", b""),
    _run_weights("list", "w.pt", "w.pt", lambda: _checkpoint([1])),
    _run_weights("onnx-garbage", "g.onnx", "g.onnx", b"\x08\x01garbage onnx", "neural-onnx"),
    _run_weights("onnx-empty", "g.onnx", "g.onnx", b"", "neural-onnx"),
    Case("ld-export-wrong-shape", ("ld", "export-onnx", "--weights", "{ws}/w.pt", "--out", "{ws}/e.onnx"), "w.pt",
         {"w.pt": _wrong_shape}),
    Case("ld-average-wrong-width", ("ld", "average", "--out", "{ws}/m.pt", "{ws}/a.pt", "{ws}/b.pt"), "a.pt",
         {"a.pt": _wrong_width, "b.pt": _wrong_width}),
    _run_weights("wrong-width", "width 32", "w.pt", _wrong_width),
    _run_weights("huge-width", "width", "w.pt", lambda: _checkpoint({"state_dict": {}, "width": 10**9})),
]

MCAP_MAGIC = b"\x89MCAP0\r\n"
MCAP = [
    Case("replay-empty", ("replay", "{ws}/e.mcap", "--track", "slr", "--out", "{ws}/r"), "e.mcap", {"e.mcap": b""}),
    Case("replay-truncated", ("replay", "{ws}/t.mcap", "--track", "slr", "--out", "{ws}/r"), "t.mcap",
         {"t.mcap": MCAP_MAGIC + b"\x01\x10\x00\x00"}),
    Case("replay-garbage", ("replay", "{ws}/g.mcap", "--track", "slr", "--out", "{ws}/r"), "g.mcap",
         {"g.mcap": MCAP_MAGIC + bytes(range(256)) * 4}),
]

ASC_HEAD = "date Sun Nov 29 05:31:23.365 2026\nbase hex  timestamps absolute\nBegin Triggerblock\n"
CAN_LOGS = [
    Case("hil-replay-garbage-asc", ("hil", "replay", "{ws}/g.asc"), "g.asc", {"g.asc": "\x00\xffnot a log\n" * 5}),
    Case("hil-replay-garbage-blf", ("hil", "replay", "{ws}/g.blf"), "g.blf", {"g.blf": b"LOGG" + b"\xff" * 200}),
    Case("hil-replay-garbage-txt", ("hil", "replay", "{ws}/g.txt"), "g.txt", {"g.txt": "1 2 3\n"}),
    Case("hil-replay-empty", ("hil", "replay", "{ws}/e.asc"), "e.asc", {"e.asc": ""}),
]


def _npz(**arrays) -> bytes:
    import numpy as np

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _pickled() -> bytes:
    import numpy as np

    return _npz(images=np.array([object()], dtype=object))


def _missing_key() -> bytes:
    import numpy as np

    return _npz(images=np.zeros(3))


DATASETS = [
    Case("ld-train-missing-key", ("ld", "train", "--data", "{ws}/ds", "--epochs", "1", "--out", "{ws}/w.pt"),
         "shard_00000.npz", {"ds/dataset.json": "{}", "ds/shard_00000.npz": _missing_key}),
    Case("ld-train-pickled", ("ld", "train", "--data", "{ws}/ds", "--epochs", "1", "--out", "{ws}/w.pt"),
         "shard_00000.npz", {"ds/dataset.json": "{}", "ds/shard_00000.npz": _pickled}),
    Case("ld-train-garbage-shard", ("ld", "train", "--data", "{ws}/ds", "--epochs", "1", "--out", "{ws}/w.pt"),
         "shard_00000.npz", {"ds/dataset.json": "{}", "ds/shard_00000.npz": b"PK\x03\x04garbage"}),
    Case("ld-eval-pickled", ("ld", "eval", "--data", "{ws}/ds", "--out", "{ws}/e"), "shard_00000.npz",
         {"ds/dataset.json": "{}", "ds/shard_00000.npz": _pickled}),
]

SUMMARY_OK = json.dumps(fake_summary(scenario="x", defense="none", max_abs_dev_m=0.1).model_dump(mode="json"))
RUN_FOLDERS = [
    Case("compare-summary-list", ("compare", "{ws}/bad", "--out", "{ws}/cmp"), "summary.json",
         {"bad/summary.json": "[]", "bad/trajectory.csv": "t\n"}),
    Case("compare-trajectory-garbage", ("compare", "{ws}/bad", "--out", "{ws}/cmp"), "trajectory.csv",
         {"bad/summary.json": SUMMARY_OK, "bad/trajectory.csv": "\x00\x01\x02garbage,,\n\xff\n"}),
    Case("compare-trajectory-empty", ("compare", "{ws}/bad", "--out", "{ws}/cmp"), "trajectory.csv",
         {"bad/summary.json": SUMMARY_OK, "bad/trajectory.csv": ""}),
    Case("compare-trajectory-text", ("compare", "{ws}/bad", "--out", "{ws}/cmp"), "trajectory.csv",
         {"bad/summary.json": SUMMARY_OK, "bad/trajectory.csv": "t,phys_dev\nabc,def\n"}),
    Case("replay-summary-list", ("replay", "{ws}/d/run.mcap", "--out", "{ws}/r"), "summary.json",
         {"d/summary.json": "[]", "d/run.mcap": b"x"}),
    Case("replay-summary-garbage", ("replay", "{ws}/d/run.mcap", "--out", "{ws}/r"), "summary.json",
         {"d/summary.json": b"\xff\xfe{", "d/run.mcap": b"x"}),
    Case("replay-summary-track-number", ("replay", "{ws}/d/run.mcap", "--out", "{ws}/r"), "track is not a string",
         {"d/summary.json": '{"track": 5, "defense": "ld3"}', "d/run.mcap": b"x"}),
    Case("replay-summary-params-list", ("replay", "{ws}/d/run.mcap", "--out", "{ws}/r"), "defense_params",
         {"d/summary.json": '{"track": "slr", "defense_params": [1, 2]}', "d/run.mcap": b"x"}),
    Case("compare-summary-old-version", ("compare", "{ws}/bad", "--out", "{ws}/cmp"), "max_abs_dev_m",
         {"bad/summary.json": SUMMARY_OK.replace('"max_abs_dev_m": 0.1', '"max_abs_dev_m": "far"'),
          "bad/trajectory.csv": "t,phys_dev\n0,0\n"}),
    Case("campaign-summary-old-version", ("campaign", "table4", "--runs", "ld3-start6", "--detector", "oracle",
                                          "--out", "{ws}/camp"), "ld3-start6/summary.json",
         {"camp/.campaign.lock": "", "camp/ld3-start6/summary.json": '{"scenario": "old", "consequence": "hit_curb"}'}),
]

GNSS = [
    Case("vehicle-nmea-garbage", ("vehicle", "--map", "parking-lot", "--gnss", "nmea:{ws}/g.nmea", "--detector",
                                  "none", "--defense", "none", "--duration", "2", "--out", "{ws}/v"), "g.nmea",
         {"g.nmea": b"\x00\xff$GPGGA,garbage*ZZ\r\n" * 20}),
]

TRACES = [
    Case("trace-random-bytes", ("run", "slr", "--duration", "2", "--localization", "msf", "--attack",
                                "trace:trace={ws}/t.csv,start=0", "--out", "{ws}/r"), "t.csv",
         {"t.csv": bytes(range(256))}),
]

DEEP = 100_000
TEXT_FILES = [
    Case("toml-nested-deep", ("run", "{ws}/s.toml", "--out", "{ws}/out"), "s.toml",
         {"s.toml": "x = " + "[" * DEEP + "]" * DEEP + "\n"}),
    Case("toml-nested-tables", ("run", "{ws}/s.toml", "--out", "{ws}/out"), "s.toml",
         {"s.toml": "x = " + "{a=" * 2000 + "1" + "}" * 2000 + "\n"}),
    Case("set-newline", ("run", "slr", "--duration", "2", "--set", "speed=3\nseed=5", "--out", "{ws}/out"),
         "newline"),
    Case("name-escape-sequence", ("run", "{ws}/\x1b[31mred.toml", "--out", "{ws}/out"), "red.toml"),
]

VALUES = [
    Case("campaign-timeout-inf", ("campaign", "table4", "--timeout", "inf", "--out", "{ws}/c"), "timeout"),
    Case("campaign-timeout-nan", ("campaign", "table4", "--timeout", "nan", "--out", "{ws}/c"), "timeout"),
    Case("search-timeout-inf", ("search", "local", "--threat", "msf-output", "--budget", "2", "--defense", "ld3",
                                "--localization", "msf", "--timeout", "inf", "--out", "{ws}/s"), "timeout"),
    Case("paper-timeout-inf", ("paper", "--quick", "--timeout", "inf", "--out", "{ws}/p"), "timeout"),
    Case("security-margin-timeout-inf", ("security-margin", "--timeout", "inf", "--out", "{ws}/m"), "timeout"),
    Case("ecu-duration-negative", ("ecu", "--duration", "-1"), "duration"),
    Case("ecu-duration-nan", ("ecu", "--duration", "nan"), "duration"),
    Case("ecu-estop-decel-zero", ("ecu", "--estop-decel", "0", "--duration", "1"), "estop-decel"),
    Case("ecu-max-steer-nan", ("ecu", "--max-steer-deg", "nan", "--duration", "1"), "max-steer-deg"),
    Case("ecu-max-steer-rate-negative", ("ecu", "--max-steer-rate-deg", "-5", "--duration", "1"),
         "max-steer-rate-deg"),
    Case("ecu-plant-wheelbase", ("ecu", "--plant-arg", "wheelbase=-1", "--duration", "1"), "wheelbase"),
    Case("ecu-plant-arg-nan", ("ecu", "--plant-arg", "wheelbase=nan", "--duration", "1"), "wheelbase"),
    Case("hil-drill-nan", ("hil", "parking-lot", "--duration", "2", "--drill", "report_timeout@nan", "--out",
                           "{ws}/h"), "nan"),
    Case("hil-drill-after-end", ("hil", "parking-lot", "--duration", "2", "--drill", "report_timeout@1e9", "--out",
                                 "{ws}/h"), "1e9"),
    Case("hil-drill-negative", ("hil", "parking-lot", "--duration", "2", "--drill", "report_timeout@-1", "--out",
                                "{ws}/h"), "-1"),
    Case("hil-duration-nan", ("hil", "parking-lot", "--duration", "nan", "--out", "{ws}/h"), "duration"),
    Case("ld-train-lr-nan", ("ld", "train", "--data", "{ws}/nodata", "--lr", "nan", "--out", "{ws}/w.pt"), "--lr"),
    Case("ld-train-lr-zero", ("ld", "train", "--data", "{ws}/nodata", "--lr", "0", "--out", "{ws}/w.pt"), "--lr"),
    Case("ld-train-threads-zero", ("ld", "train", "--data", "{ws}/nodata", "--threads", "0", "--out", "{ws}/w.pt"),
         "--threads"),
    Case("ld-train-epochs-zero", ("ld", "train", "--data", "{ws}/nodata", "--epochs", "0", "--out", "{ws}/w.pt"),
         "--epochs"),
    Case("ld-dataset-frames-zero", ("ld", "dataset", "--out", "{ws}/d", "--frames", "0"), "--frames"),
    Case("ld-dataset-seed-negative", ("ld", "dataset", "--out", "{ws}/d", "--frames", "2", "--seed", "-1"),
         "--seed"),
    Case("ld-dataset-onto-dataset", ("ld", "dataset", "--out", "{ws}/ds", "--frames", "2"), "ds",
         {"ds/dataset.json": "{}", "ds/shard_00000.npz": b"keep"}),
    Case("ld-dataset-foreign", ("ld", "dataset", "--out", "{ws}/foreign", "--frames", "2"), "foreign"),
]

def _grey_png() -> bytes:
    import cv2
    import numpy as np

    return cv2.imencode(".png", np.full((160, 320, 3), 90, np.uint8))[1].tobytes()


OUTPUT_PLACES = [
    Case("paper-onto-campaign", ("paper", "--quick", "--out", "{ws}/camp"), "camp",
         {"camp/runs.csv": "run_id\n", "camp/report.md": "mine", "camp/slr-0/summary.json": "{}"}),
    Case("compare-out-foreign", ("compare", "{ws}/prev", "--out", "{ws}/foreign"), "foreign"),
    Case("replay-out-foreign", ("replay", "{ws}/e.mcap", "--out", "{ws}/foreign"), "foreign", {"e.mcap": b"x"}),
    Case("ld-eval-out-foreign", ("ld", "eval", "--data", "{ws}/nodata", "--out", "{ws}/foreign"), "foreign"),
    Case("demo-out-foreign", ("demo", "--out", "{ws}/foreign"), "foreign"),
    Case("ld-detect-out-foreign", ("ld", "detect", "--camera", "images:{ws}/f.png", "--detector", "classical",
                                   "--out", "{ws}/foreign"), "foreign", {"f.png": _grey_png}),
    Case("ld-closed-loop-out-foreign", ("ld", "closed-loop", "--presets", "slr", "--out", "{ws}/foreign"), "foreign"),
    Case("ld-export-onnx-out-dir", ("ld", "export-onnx", "--out", "{ws}/foreign"), "foreign"),
    Case("ld-average-out-suffix", ("ld", "average", "--out", "{ws}/m.txt", "{ws}/a.pt", "{ws}/b.pt"), ".pt"),
    Case("schema-out-dir", ("schema", "--out", "{ws}/foreign"), "foreign"),
    Case("tracks-export-out-device", ("tracks", "export", "slr", "--out", "/dev/null"), "/dev/null"),
    Case("tracks-show-out-device", ("tracks", "show", "slr", "--out", "/dev/full"), "/dev/full"),
    Case("tracks-show-out-dir", ("tracks", "show", "slr", "--out", "{ws}/foreign"), "foreign"),
    Case("tracks-show-no-extension", ("tracks", "show", "slr", "--out", "{ws}/plot"), ".png"),
    Case("patch-figure-no-extension", ("patch-figure", "--out", "{ws}/fig"), ".png"),
]

HOSTILE = [*OPENDRIVE, *PROFILES, *CHECKPOINTS, *MCAP, *CAN_LOGS, *DATASETS, *RUN_FOLDERS, *GNSS, *TRACES,
           *TEXT_FILES, *VALUES, *OUTPUT_PLACES]


ACCEPTED = [
    Case("hil-replay-far-stamp", ("hil", "replay", "{ws}/f.asc"), "replayed 2 frames",
         {"f.asc": ASC_HEAD + " 0.000000 1  130             Tx   d 8 00 04 00 00 00 00 00 04\n"
                              " 99999.000000 1  130             Tx   d 8 01 04 00 00 00 00 01 04\n"}),
    *(Case(f"scenario-name-{i}", ("run", f"{{ws}}/{name}", "--out", "{ws}/out"), "consequence", {name: GOOD})
      for i, name in enumerate(("my scen ário.toml", "straße.toml", "scenario (1).toml", ".hidden.toml"))),
]
"""Hostile-looking inputs that are valid: each runs to exit 0 within the time bound, its output in --out."""
