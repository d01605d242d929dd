"""The table of bad and hostile inputs to `ld3`: each case is an argv (with `{ws}` for the workspace), the
files it needs, and a piece of the one line it must be refused with."""

from __future__ import annotations

from dataclasses import dataclass, field

GOOD = 'track = "slr"\nduration = 2.0\n'


@dataclass(frozen=True)
class Case:
    id: str
    argv: tuple[str, ...]
    says: str
    """A piece of the one-line refusal (case-insensitive)."""
    files: dict[str, str | bytes] = field(default_factory=dict)
    """Files to create in the workspace first (path -> content)."""


def _png(width: int, height: int) -> bytes:
    """A grey PNG picture of that size."""
    import cv2
    import numpy as np

    return cv2.imencode(".png", np.full((height, width, 3), 90, np.uint8))[1].tobytes()


def _toml(id: str, text: str, says: str) -> Case:
    return Case(f"toml-{id}", ("run", "{ws}/s.toml", "--out", "{ws}/out"), says, {"s.toml": text})


def _set(id: str, setting: str, says: str, *extra: str) -> Case:
    return Case(f"set-{id}", ("run", "slr", "--duration", "2", *extra, "--set", setting, "--out", "{ws}/out"), says)


def _flag(id: str, says: str, *flags: str) -> Case:
    return Case(f"flag-{id}", ("run", "slr", *flags, "--out", "{ws}/out"), says)


SCENARIO_FILES = [
    _toml("malformed", "track = ", "malformed TOML"),
    _toml("no-track", "speed = 3.0\n", "'track' is required"),
    _toml("unknown-key", GOOD + "wheels = 3\n", "unknown keys"),
    _toml("speed-text", GOOD + 'speed = "fast"\n', "speed must be a number"),
    _toml("speed-bool", GOOD + "speed = true\n", "speed must be a number"),
    _toml("speed-negative", GOOD + "speed = -1\n", "speed must be > 0"),
    _toml("speed-zero", GOOD + "speed = 0\n", "speed must be > 0"),
    _toml("speed-nan", GOOD + "speed = nan\n", "speed must be finite"),
    _toml("speed-huge", GOOD + "speed = 1e9\n", "speed must be <="),
    _toml("duration-inf", 'track = "slr"\nduration = inf\n', "duration must be finite"),
    _toml("duration-zero", 'track = "slr"\nduration = 0\n', "duration must be > 0"),
    _toml("seed-float", GOOD + "seed = 1.5\n", "seed must be an integer"),
    _toml("seed-negative", GOOD + "seed = -1\n", "seed must be >= 0"),
    _toml("seed-bool", GOOD + "seed = true\n", "seed must be an integer"),
    _toml("lane-negative", GOOD + "lane = -1\n", "lane must be >= 0"),
    _toml("lane-missing", GOOD + "lane = 9\n", "lane 9 does not exist"),
    _toml("start-negative", GOOD + "start_s = -5\n", "start_s must be >= 0"),
    _toml("start-beyond", GOOD + "start_s = 1e7\n", "start_s"),
    _toml("track-unknown", 'track = "moon"\n', "unknown track preset 'moon'"),
    _toml("track-bad-seed", 'track = "local@abc"\n', "bad seed 'abc'"),
    _toml("track-number", "track = 5\n", "track must be a string"),
    _toml("vehicle-unknown", GOOD + 'vehicle = "tank"\n', "unknown vehicle 'tank'"),
    _toml("condition-unknown", GOOD + 'condition = "snow"\n', "unknown condition 'snow'"),
    _toml("name-escape", GOOD + 'name = "../escape"\n', "one path component"),
    _toml("name-absolute", GOOD + 'name = "/tmp/x"\n', "one path component"),
    _toml("name-empty", GOOD + 'name = ""\n', "one path component"),
    _toml("name-hidden", GOOD + 'name = ".hidden"\n', "one path component"),
    _toml("rates-zero", GOOD + "[rates]\ncontrol_hz = 0\n", "rates.control_hz must be > 0"),
    _toml("rates-negative", GOOD + "[rates]\ncontrol_hz = -100\n", "rates.control_hz must be > 0"),
    _toml("rates-misspelt", GOOD + "[rates]\ncontrol_hertz = 50\n", "unknown scenario key 'rates.control_hertz'"),
    _toml("rates-camera-fast", GOOD + "[rates]\ncamera_hz = 200\n", "camera_hz (200) must not exceed"),
    _toml("rates-control-fast", GOOD + "[rates]\ncontrol_hz = 500\n", "control_hz (500) must not exceed"),
    _toml("rates-control-over-physics", GOOD + "[rates]\ncontrol_hz = 100\n",
          "raise rates.physics_hz with it, e.g. rates.physics_hz=100"),
    _toml("rates-camera-uneven", GOOD + "[rates]\ncontrol_hz = 50\n", "camera_hz (20) must divide rates.control_hz"),
    _toml("rates-gnss-fast", GOOD + "[rates.localization]\ngnss_hz = 150\n", "gnss_hz (150) must not exceed"),
    _toml("rates-text", GOOD + '[rates]\nphysics_hz = "fast"\n', "rates.physics_hz must be a number"),
    _toml("rates-not-table", GOOD + "rates = 5\n", "rates"),
    _toml("rates-hold-negative", GOOD + "[rates]\ncommand_hold_s = -1\n", "command_hold_s must be >= 0"),
    _toml("rates-gnss-zero", GOOD + "[rates.localization]\ngnss_hz = 0\n", "gnss_hz must be a number > 0"),
    _toml("rates-loc-unknown", GOOD + "[rates.localization]\nradar_hz = 5\n", "unknown localization parameter"),
    _toml("traffic-misspelt", GOOD + "[traffic]\nvehicle_count = 3\n", "unknown scenario key 'traffic.vehicle_count'"),
    _toml("traffic-negative", GOOD + "[traffic]\nvehicles = -2\n", "traffic.vehicles must be >= 0"),
    _toml("traffic-idle", GOOD + "[traffic]\ngap = 12.0\n", "traffic.vehicles = 0, so traffic.gap would change"),
    _toml("traffic-no-lane", GOOD + "[traffic]\nvehicles = 2\nlanes = [3]\n", "traffic.lanes names lane 3"),
    _set("traffic-too-many", "traffic.vehicles=60", "off the road"),
    _toml("defense-unknown", GOOD + '[defense]\nkind = "moat"\n', "unknown defense 'moat'"),
    _toml("defense-param-text", GOOD + '[defense]\nkind = "ld3"\nb = "x"\n', "'b' must be a number"),
    _toml("defense-param-unknown", GOOD + '[defense]\nkind = "ld3"\nbeta = 1\n', "beta"),
    _toml("defense-param-unread", GOOD + '[defense]\nkind = "savior"\nheading = "msf"\n', "not read by defense"),
    _toml("defense-number", GOOD + "defense = 3\n", "defense must be a string"),
    _toml("detector-unknown", GOOD + '[detector]\nkind = "eyes"\n', "unknown lane detector 'eyes'"),
    _toml("detector-param-unknown", GOOD + '[detector]\nkind = "neural"\nzoom = 2\n', "unknown parameter 'zoom'"),
    _toml("attack-no-kind", GOOD + "[attack]\nstart = 1\n", "needs a 'kind'"),
    _toml("attack-unknown", GOOD + '[attack]\nkind = "laser"\n', "laser"),
    _toml("attack-bad-param", GOOD + '[attack]\nkind = "fusionripper"\nd = "far"\n', "'d' must be a number"),
    _toml("attack-empty-list", GOOD + "attack = []\n", "non-empty list"),
    _toml("attack-number", GOOD + "attack = 5\n", "attack"),
    _toml("attack-after-end", GOOD + '[attack]\nkind = "fusionripper"\nstart = 30\n', "would never act"),
    _toml("stop-after-end", GOOD + "stop_at = 100\n", "after the run's end"),
    _toml("stop-decel-zero", GOOD + "stop_at = 1\nstop_decel = 0\n", "stop_decel must be > 0"),
    _toml("needs-unmet", GOOD + 'defense = "ld3"\ndetector = "none"\n', "has no effect"),
    Case("toml-binary", ("run", "{ws}/s.toml", "--out", "{ws}/out"), "not a text", {"s.toml": b"\x00\xff\xfe\x01"}),
    Case("toml-missing", ("run", "{ws}/nope.toml", "--out", "{ws}/out"), "scenario file not found"),
    Case("toml-folder", ("run", "{ws}/dir.toml", "--out", "{ws}/out"), "scenario file not found",
         {"dir.toml/x": ""}),
    Case("scenario-unknown", ("run", "nosuch", "--out", "{ws}/out"), "unknown scenario 'nosuch'"),
]

SETTINGS = [
    _set("speed-text", "speed=fast", "speed must be a number"),
    _set("seed-float", "seed=1.5", "seed must be an integer"),
    _set("speed-bool", "speed=true", "speed must be a number"),
    _set("rates-zero", "rates.control_hz=0", "rates.control_hz must be > 0"),
    _set("rates-unknown", "rates.control_hertz=5", "unknown scenario key 'rates.control_hertz'"),
    _set("rates-loc-zero", "rates.localization.gnss_hz=0", "gnss_hz must be a number > 0"),
    _set("rates-camera-uneven", "rates.control_hz=30", "a frame every 2 ticks would be 15 Hz"),
    _set("rates-lidar-fast", "rates.localization.lidar_hz=200", "lidar_hz (200) must not exceed"),
    _set("rates-into-value", "rates.control_hz.x=1", "is a value, not a table"),
    _set("unknown-key", "wheels=3", "unknown scenario key 'wheels'"),
    _set("no-equals", "speed", "expected KEY=VALUE"),
    _set("no-key", "=5", "expected KEY=VALUE"),
    _set("attack-none", "attack.start=5", "has no attack"),
    _set("defense-text", "defense.b=x", "must be a number", "--defense", "ld3", "--localization", "msf"),
    _set("unknown-section", "engine.power=5", "unknown section 'engine'"),
    Case("set-attack-index", ("run", "slr", "--attack", "trace:default", "--attack", "fusionripper", "--localization",
                              "msf", "--set", "attack.3.start=1", "--out", "{ws}/out"), "composes 2 attacks"),
    _set("name-escape", "name=../../x", "one path component"),
    _set("track-unknown", "track=moon", "unknown track preset 'moon'"),
    _set("duration-inf", "duration=inf", "duration must be finite"),
    _set("lane-text", "lane=left", "lane must be an integer"),
    _set("detector-kind", "detector.kind=eyes", "unknown lane detector 'eyes'"),
    _set("defense-kind", "defense.kind=moat", "unknown defense 'moat'"),
]

FLAGS = [
    _flag("duration-inf", "duration must be finite", "--duration", "inf"),
    _flag("duration-negative", "duration must be > 0", "--duration", "-5"),
    _flag("duration-text", "invalid float value", "--duration", "abc"),
    _flag("speed-nan", "speed must be finite", "--speed", "nan"),
    _flag("seed-negative", "seed must be >= 0", "--seed", "-3"),
    _flag("track-bad-seed", "bad seed 'abc'", "--track", "local@abc"),
    _flag("track-unknown", "unknown track preset 'moon'", "--track", "moon"),
    _flag("attack-unknown", "laser", "--attack", "laser"),
    _flag("attack-no-value", "is not key=value", "--attack", "fusionripper:d", "--localization", "msf"),
    _flag("attack-twice", "given twice", "--attack", "fusionripper:d=1,d=2", "--localization", "msf"),
    _flag("attack-empty", "empty attack spec", "--attack", ":x"),
    _flag("attack-trace-unknown", "nosuchtrace", "--attack", "trace:nosuchtrace", "--localization", "msf"),
    _flag("attack-after-end", "would never act", "--attack", "fusionripper:start=1000", "--localization", "msf"),
    _flag("lane-missing", "lane 99 does not exist", "--lane", "99", "--duration", "2"),
    _flag("condition-unknown", "unknown condition 'snow'", "--condition", "snow"),
    _flag("defense-unknown", "invalid choice", "--defense", "moat"),
    _flag("speed-beyond-vehicle", "beyond what", "--speed", "90", "--duration", "2"),
]

OUTPUTS = [
    Case("out-file", ("run", "slr", "--duration", "2", "--out", "{ws}/afile"), "is a file"),
    Case("out-finished-run", ("run", "slr", "--duration", "2", "--out", "{ws}/prev"), "holds a finished run"),
    Case("out-foreign", ("run", "slr", "--duration", "2", "--out", "{ws}/foreign"), "not a run"),
    Case("out-under-file", ("run", "slr", "--duration", "2", "--out", "{ws}/afile/sub"), "cannot write"),
    Case("campaign-out-file", ("campaign", "table4", "--out", "{ws}/afile"), "afile"),
    Case("campaign-out-foreign", ("campaign", "table4", "--out", "{ws}/foreign"), "foreign"),
    Case("search-out-file", ("search", "local", "--threat", "msf-output", "--budget", "2", "--defense", "ld3",
                             "--localization", "msf", "--out", "{ws}/afile"), "afile"),
    Case("search-out-foreign", ("search", "local", "--threat", "msf-output", "--budget", "2", "--defense", "ld3",
                                "--localization", "msf", "--out", "{ws}/foreign"), "foreign"),
    Case("demo-out-file", ("demo", "--out", "{ws}/afile"), "afile"),
    Case("paper-out-file", ("paper", "--out", "{ws}/afile"), "afile"),
    Case("schema-out-missing-dir", ("schema", "--out", "{ws}/no/such/dir/schema.json"), "no such file"),
    Case("compare-out-file", ("compare", "{ws}/prev", "--out", "{ws}/afile"), "afile"),
]

OTHER_COMMANDS = [
    Case("tracks-bad-seed", ("tracks", "show", "local@abc"), "bad seed 'abc'"),
    Case("tracks-unknown", ("tracks", "show", "moon"), "unknown track preset 'moon'"),
    Case("tracks-xodr-missing", ("tracks", "show", "xodr:{ws}/none.xodr", "--out", "{ws}/t.png"), "none.xodr"),
    Case("tracks-xodr-not-xml", ("run", "slr", "--track", "xodr:{ws}/afile", "--out", "{ws}/out"), "afile"),
    Case("tracks-xodr-route", ("run", "slr", "--track", "xodr:{ws}/r.xodr#9,7", "--out", "{ws}/out"), "r.xodr",
         {"r.xodr": '<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="7"/></OpenDRIVE>'}),
    Case("tracks-export-unknown", ("tracks", "export", "moon", "--format", "xodr", "--out", "{ws}/m.xodr"), "moon"),
    Case("tracks-export-format", ("tracks", "export", "slr", "--format", "svg", "--out", "{ws}/m.svg"), "svg"),
    Case("tracks-export-out-dir", ("tracks", "export", "slr", "--format", "xodr", "--out", "{ws}/foreign"),
         "foreign"),
    Case("compare-missing", ("compare", "{ws}/nope", "--out", "{ws}/cmp"), "nope"),
    Case("compare-not-run", ("compare", "{ws}/foreign", "--out", "{ws}/cmp"), "foreign"),
    Case("compare-corrupt", ("compare", "{ws}/corrupt", "--out", "{ws}/cmp"), "summary.json",
         {"corrupt/summary.json": "{not json", "corrupt/trajectory.csv": "t\n"}),
    Case("campaign-unknown", ("campaign", "nosuch", "--out", "{ws}/c"), "unknown campaign 'nosuch'"),
    Case("campaign-no-runs", ("campaign", "table4", "--runs", "zzz*", "--out", "{ws}/c"), "zzz*"),
    Case("campaign-workers-zero", ("campaign", "table4", "--workers", "0", "--out", "{ws}/c"), "workers"),
    Case("campaign-backend", ("campaign", "table4", "--backend", "slurm", "--out", "{ws}/c"), "slurm"),
    Case("campaign-budget", ("campaign", "table4", "--budget", "3", "--out", "{ws}/c"), "budget"),
    Case("campaign-timeout", ("campaign", "table4", "--timeout", "-1", "--out", "{ws}/c"), "timeout"),
    Case("campaign-set", ("campaign", "table4", "--set", "speed=fast", "--out", "{ws}/c"), "speed must be a number"),
    Case("campaign-attack", ("campaign", "table4", "--attack", "laser", "--out", "{ws}/c"), "laser"),
    Case("search-scenario", ("search", "nosuch", "--threat", "gnss", "--budget", "2", "--out", "{ws}/s"),
         "unknown scenario 'nosuch'"),
    Case("search-threat", ("search", "local", "--threat", "telepathy", "--budget", "2", "--out", "{ws}/s"),
         "telepathy"),
    Case("search-budget", ("search", "local", "--threat", "gnss", "--budget", "0", "--out", "{ws}/s"), "budget"),
    Case("search-no-defense", ("search", "local", "--threat", "gnss", "--budget", "2", "--paper-mode",
                               "--out", "{ws}/s"), "paper-mode"),
    Case("search-set", ("search", "local", "--threat", "gnss", "--budget", "2", "--set", "seed=-1",
                        "--out", "{ws}/s"), "seed must be >= 0"),
    Case("hil-scenario", ("hil", "nosuch", "--out", "{ws}/h"), "unknown scenario 'nosuch'"),
    Case("hil-interface", ("hil", "parking-lot", "--interface", "warpdrive", "--out", "{ws}/h"), "warpdrive"),
    Case("hil-channel", ("hil", "parking-lot", "--interface", "slcan", "--channel", "{ws}/no-tty",
                         "--out", "{ws}/h"), "no-tty"),
    Case("hil-profile", ("hil", "parking-lot", "--profile", "nosuch", "--out", "{ws}/h"), "nosuch"),
    Case("hil-drill", ("hil", "parking-lot", "--drill", "meteor", "--out", "{ws}/h"), "meteor"),
    Case("hil-drill-time", ("hil", "parking-lot", "--drill", "ecu_lost@soon", "--out", "{ws}/h"), "soon"),
    Case("hil-out-finished-run", ("hil", "parking-lot", "--duration", "2", "--out", "{ws}/prev"),
         "holds a finished run"),
    Case("hil-set", ("hil", "parking-lot", "--set", "rates.control_hz=0", "--out", "{ws}/h"),
         "rates.control_hz must be > 0"),
    Case("ecu-interface", ("ecu", "--interface", "warpdrive"), "warpdrive"),
    Case("ecu-plant-arg", ("ecu", "--plant", "pybullet", "--plant-arg", "start_s=far"), "start_s"),
    Case("ecu-plant-arg-form", ("ecu", "--plant", "pybullet", "--plant-arg", "start_s"), "KEY=VALUE"),
    Case("ecu-profile", ("ecu", "--profile", "nosuch"), "nosuch"),
    Case("ld-eval-data", ("ld", "eval", "--data", "{ws}/nodata", "--out", "{ws}/e"), "nodata"),
    Case("ld-export-weights", ("ld", "export-onnx", "--weights", "{ws}/no.pt", "--out", "{ws}/e.onnx"), "no.pt"),
    Case("ld-train-data", ("ld", "train", "--data", "{ws}/nodata", "--out", "{ws}/w.pt"), "nodata"),
    Case("ld-closed-loop-preset", ("ld", "closed-loop", "--presets", "moon", "--out", "{ws}/cl"), "moon"),
    Case("ld-closed-loop-no-detector", ("ld", "closed-loop", "--detector", "none", "--out", "{ws}/cl"),
         "needs a lane detector"),
    Case("ld-closed-loop-layouts", ("ld", "closed-loop", "--layouts", "mine", "--out", "{ws}/cl"), "--layouts"),
    Case("ld-closed-loop-duration", ("ld", "closed-loop", "--duration", "-1", "--out", "{ws}/cl"), "duration"),
    Case("ld-closed-loop-traffic", ("ld", "closed-loop", "--traffic", "-1", "--out", "{ws}/cl"), "number of cars"),
    Case("ld-closed-loop-traffic-text", ("ld", "closed-loop", "--traffic", "many", "--out", "{ws}/cl"),
         "number of cars"),
    Case("ld-closed-loop-traffic-full", ("ld", "closed-loop", "--presets", "parking-lot", "--traffic", "20", "--out",
                                         "{ws}/cl"), "lower --traffic"),
    Case("ld-closed-loop-lead-gap", ("ld", "closed-loop", "--lead-gap", "10", "--out", "{ws}/cl"), "add --traffic"),
    Case("ld-closed-loop-lead-gap-zero", ("ld", "closed-loop", "--traffic", "6", "--lead-gap", "0", "--out",
                                          "{ws}/cl"), "--lead-gap must"),
    Case("ld-dataset-traffic", ("ld", "dataset", "--out", "{ws}/d", "--frames", "2", "--traffic", "-2"),
         "number of cars"),
    Case("ld-detect-camera", ("ld", "detect", "--camera", "usb:0", "--out", "{ws}/d"), "--camera takes"),
    Case("ld-detect-no-images", ("ld", "detect", "--camera", "images:{ws}/none*.png", "--out", "{ws}/d"),
         "no image matches"),
    Case("ld-detect-video", ("ld", "detect", "--camera", "video:{ws}/afile", "--out", "{ws}/d"), "cannot open camera"),
    Case("ld-detect-size", ("ld", "detect", "--camera", "images:{ws}/f.png", "--out", "{ws}/d"),
         "give --calibration", {"f.png": _png(64, 32)}),
    Case("ld-detect-calibration", ("ld", "detect", "--camera", "images:{ws}/f.png", "--calibration", "{ws}/no.toml",
                                   "--out", "{ws}/d"), "no.toml", {"f.png": _png(64, 32)}),
    Case("ld-detect-calibration-size", ("ld", "detect", "--camera", "images:{ws}/f.png", "--calibration",
                                        "{ws}/c.toml", "--out", "{ws}/d"), "the calibration's 640x360",
         {"f.png": _png(64, 32), "c.toml": "[intrinsics]\nwidth = 640\nheight = 360\nfx = 500\nfy = 500\n"
                                           "cx = 320\ncy = 180\n[extrinsics]\nmount_x = 0\nmount_height = 1.2\n"
                                           "pitch_deg = 0\n"}),
    Case("ld-detect-frames", ("ld", "detect", "--camera", "images:{ws}/f.png", "--frames", "0", "--out", "{ws}/d"),
         "--frames", {"f.png": _png(64, 32)}),
    Case("ld-detect-oracle", ("ld", "detect", "--camera", "usb:0", "--detector", "oracle", "--out", "{ws}/d"),
         "does not read a camera"),
    Case("ld-existence-refit-data", ("ld", "existence-refit", "--data", "{ws}/nodata", "--out", "{ws}/w.pt"),
         "nodata"),
    Case("ld-existence-refit-negatives", ("ld", "existence-refit", "--data", "{ws}/nodata", "--negatives", "0",
                                          "--out", "{ws}/w.pt"), "--negatives"),
    Case("ld-average-one", ("ld", "average", "--out", "{ws}/m.pt", "{ws}/afile"), "at least two checkpoints"),
    Case("ld-average-not-checkpoint", ("ld", "average", "--out", "{ws}/m.pt", "{ws}/afile", "{ws}/afile"),
         "not a torch file"),
    Case("ld-average-missing", ("ld", "average", "--out", "{ws}/m.pt", "{ws}/none.pt", "{ws}/afile"), "none.pt"),
    Case("run-weights-not-checkpoint", ("run", "highway", "--detector", "neural", "--set",
                                        "detector.weights={ws}/afile", "--out", "{ws}/r"), "not a torch file"),
    Case("ld-dataset-preset", ("ld", "dataset", "--out", "{ws}/d", "--frames", "2", "--presets", "mars"),
         "presets must be distinct names among slr"),
    Case("ld-dataset-condition", ("ld", "dataset", "--out", "{ws}/d", "--frames", "2", "--conditions", "fog"),
         "conditions must be distinct names among day"),
    Case("bench-scenario", ("bench", "loop", "--scenario", "nosuch"), "unknown scenario 'nosuch'"),
    Case("bench-seconds", ("bench", "loop", "--seconds", "-1"), "duration must be > 0"),
    Case("replay-missing", ("replay", "{ws}/none.mcap", "--out", "{ws}/r"), "none.mcap"),
    Case("replay-not-mcap", ("replay", "{ws}/afile", "--out", "{ws}/r"), "afile"),
    Case("vehicle-map", ("vehicle", "--map", "moon", "--gnss", "nmea:{ws}/afile", "--detector", "none",
                         "--defense", "none", "--out", "{ws}/v"), "moon"),
    Case("vehicle-gnss", ("vehicle", "--map", "parking-lot", "--gnss", "carrier-pigeon", "--detector", "none",
                          "--defense", "none", "--out", "{ws}/v"), "carrier-pigeon"),
    Case("vehicle-speed", ("vehicle", "--map", "parking-lot", "--gnss", "nmea:{ws}/afile", "--detector", "none",
                           "--defense", "none", "--speed", "-1", "--out", "{ws}/v"), "speed"),
    Case("vehicle-camera", ("vehicle", "--map", "parking-lot", "--gnss", "nmea:{ws}/afile", "--camera",
                            "video:{ws}/none.mp4", "--out", "{ws}/v"), "none.mp4"),
    Case("vehicle-force-refused-start", ("vehicle", "--map", "parking-lot", "--gnss", "carrier-pigeon", "--detector",
                                         "none", "--defense", "none", "--out", "{ws}/prev", "--force"),
         "carrier-pigeon"),
    Case("hil-force-refused-start", ("hil", "parking-lot", "--duration", "2", "--log", "{ws}/afile/can.asc",
                                     "--out", "{ws}/prev", "--force"), "afile"),
    Case("vehicle-out-finished", ("vehicle", "--map", "parking-lot", "--gnss", "nmea:{ws}/afile", "--detector",
                                  "none", "--out", "{ws}/prev"), "holds a finished run"),
    Case("patch-figure-out", ("patch-figure", "--out", "{ws}/afile/x.png"), "afile"),
]

CASES = [*SCENARIO_FILES, *SETTINGS, *FLAGS, *OUTPUTS, *OTHER_COMMANDS]
