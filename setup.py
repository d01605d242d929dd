"""The compiled per-tick kernels (Cython): optional, so an install without a C compiler keeps the pure-Python
path (tracks/compiled.py); the project's metadata is in pyproject.toml."""

import sys

from setuptools import Extension, setup

NO_CONTRACTION = [] if sys.platform == "win32" else ["-ffp-contract=off"]  # bit-equal to the Python reference
KERNELS = ["tracks.reference_kernels", "tracks.map_kernels", "vehicles.vehicle_kernels",
           "testbed.localization.msf_kernels", "testbed.control.planner_kernels", "testbed.control.lateral_kernels",
           "testbed.perception.detectors.label_kernels", "testbed.render_kernels",
           "tracks.paint_kernels"]

setup(ext_modules=[Extension(name, [name.replace(".", "/") + ".pyx"], optional=True,
                             extra_compile_args=NO_CONTRACTION) for name in KERNELS])
