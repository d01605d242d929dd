"""Figures are drawn through matplotlib's object API: importing the package, or any module that draws, and
drawing a figure leave the user's matplotlib backend alone (no `matplotlib.use`, no pyplot state)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("tracks", "vehicles", "testbed", "hil")


def _drawing_modules() -> list[str]:
    """Every first-party module whose source imports matplotlib, as a dotted name."""
    names = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            text = path.read_text()
            if "import matplotlib" in text or "from matplotlib" in text:
                names.append(".".join(path.relative_to(ROOT).with_suffix("").parts))
    return names


def _python(code: str) -> str:
    """Run `code` in a fresh interpreter with no MPLBACKEND set; its stdout, stripped."""
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_the_drawing_modules_are_found():
    modules = _drawing_modules()
    assert {"tracks.plot", "testbed.eval.run.birdseye", "hil.vehicle.drive_replay"} <= set(modules)


def test_importing_the_package_and_every_drawing_module_keeps_the_default_backend():
    bare = _python("import matplotlib; print(matplotlib.get_backend())")
    imported = _python(f"""
        import importlib, sys
        from testbed import api
        for name in {_drawing_modules()!r}:
            importlib.import_module(name)
        assert "matplotlib.pyplot" not in sys.modules, "pyplot imported: a backend is chosen at import"
        import matplotlib
        print(matplotlib.get_backend())
    """)
    assert imported == bare


def test_drawing_a_figure_keeps_the_backend_the_user_chose(tmp_path):
    out = _python(f"""
        import sys
        from pathlib import Path
        import matplotlib
        matplotlib.use("svg")
        from hil.vehicle.drive_replay import ReplayResult, write_replay
        from testbed.eval.experiments.paper_figures import paper_vs_ours
        out = Path({str(tmp_path)!r})
        paper_vs_ours(out / "bars.png", "t", ["a", "b"], [(0.5, 0.1), None], [(0.4, 0.1), (0.3, 0.2)], "rate")
        rows = [dict(t=0.1 * i, msf_dev=0.0, ld_dev=0.1, fused_dev=None, cusum=0.01 * i, mode="normal", r_msf=None,
                     r_ld=None) for i in range(20)]
        written = write_replay(out / "replay", ReplayResult(rows, 1.0, 0.1), "replay")
        assert "matplotlib.pyplot" not in sys.modules
        print(matplotlib.get_backend(), *written)
    """)
    assert out == "svg replay.csv replay.png"
    assert (tmp_path / "bars.png").stat().st_size > 1000
    assert (tmp_path / "replay" / "replay.png").stat().st_size > 1000
