"""The vehicle side (docs/architecture.md, "Conventions": tracks' geometry and map, localization, the
lane-detection contract, defense, control, the loop, hil) imports and its commands start with the simulator's
packages absent: a subprocess whose import system refuses them imports every vehicle-side module and prints
`ld3 hil --help`."""

from __future__ import annotations

import subprocess
import sys
import textwrap

SIMULATOR_PACKAGES = ("pybullet", "cv2", "torch", "torchvision", "matplotlib", "gymnasium", "imageio_ffmpeg", "mcap",
                      "pandas", "ray", "onnxruntime", "onnx", "control")
VEHICLE_PACKAGES = ("tracks", "vehicles", "testbed.defense", "testbed.localization", "testbed.control", "hil")
VEHICLE_MODULES = ("testbed.loop", "testbed.lane_detection", "testbed.chassis", "testbed.lane_tracker",
                   "testbed.perception.detectors.onnx_file",
                   "testbed.perception.detectors.registry", "testbed.cli")
SIMULATOR_MODULES = ("tracks.plot", "vehicles.pybullet_vehicle", "hil.emulator.campaigns", "hil.emulator.fault_drill",
                     "hil.link.mcap_can", "hil.emulator.plants", "hil.emulator.scenario_run", "hil.__main__")
"""Modules inside the vehicle packages that drive or record the simulator."""

PROBE = textwrap.dedent("""
    import contextlib, importlib, importlib.abc, io, pkgutil, sys

    BLOCKED = set(sys.argv[1].split(","))

    class Refuse(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            if name.split(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"{name} is not installed (refused)", name=name)

    sys.meta_path.insert(0, Refuse())
    skip = set(sys.argv[4].split(","))
    names = list(sys.argv[3].split(","))
    for package in sys.argv[2].split(","):
        module = importlib.import_module(package)
        names += [info.name for info in pkgutil.walk_packages(module.__path__, package + ".")]
    for name in names:
        if name not in skip:
            importlib.import_module(name)
    from testbed.cli import main
    for argv in (["--help"], ["hil", "--help"], ["vehicle", "--help"]):
        with contextlib.redirect_stdout(io.StringIO()) as text, contextlib.suppress(SystemExit):
            main(argv)
        assert "usage: ld3" in text.getvalue(), argv
    print(len(names), sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
""")


def test_vehicle_side_imports_and_starts_without_the_simulator_packages():
    done = subprocess.run(
        [sys.executable, "-c", PROBE, ",".join(SIMULATOR_PACKAGES), ",".join(VEHICLE_PACKAGES),
         ",".join(VEHICLE_MODULES), ",".join(SIMULATOR_MODULES)],
        capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    count, loaded = done.stdout.split(" ", 1)
    assert int(count) > 60 and loaded.strip() == "[]"
