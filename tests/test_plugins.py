"""A defense, a lane detector and an attack added in one place each: a plugin package, put on the path with
its entry points during the test, is found by the registries, accepted by scenario validation and the CLI,
and runs end to end with the names recorded as they are."""

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from testbed.attacks.registry import ATTACKS
from testbed.defense.registry import DEFENSES
from testbed.eval.run.runner import run_scenario
from testbed.eval.run.scenario import load_scenario
from testbed.perception.detectors.registry import DETECTORS

PLUGIN = textwrap.dedent('''
    """A third-party package that extends the testbed through entry points only."""
    from testbed.attacks.base import Attack, shift_pose
    from testbed.defense.config import DefenseConfig
    from testbed.defense.ld3 import Ld3Defense
    from testbed.localization.estimate import LocalizationEstimate
    from testbed.params import params_from_signature
    from testbed.perception.detectors.oracle import OracleLaneDetector
    from testbed.registry import Capability, Component


    class EagerLd3(Ld3Defense):
        """LD3 with a hair-trigger CUSUM."""
        name = "eager-ld3"

        def __init__(self, config):
            super().__init__(DefenseConfig(b=0.2, tau=0.05))


    class ConstantOffset(Attack):
        """Moves the localization output 0.5 m left from `start` on."""
        name = "constant-offset"

        def __init__(self, start=2.0):
            super().__init__(start)
            self.active = False

        def tamper_msf(self, est, view):
            self.active = view.t >= self.start_time
            if not self.active:
                return est
            return LocalizationEstimate(est.t, shift_pose(est.pose, view.lane_heading, 0.5), est.cov)

        def state(self):
            return {"stage": "active" if self.active else "idle", "switch_time": None,
                    "offset": 0.5 if self.active else 0.0}

        def describe(self):
            return {"kind": self.name, "start": self.start_time}


    DEFENSE = Component("eager-ld3", lambda config, bicycle: EagerLd3(config), "LD3 with b = 0.2",
                        needs=frozenset({Capability.LANE_DETECTOR}))
    DETECTOR = Component("noisy-oracle", lambda track, rig, rng: OracleLaneDetector(track, rng, noise_std=0.02),
                         "the oracle with 2 cm of noise", provides=frozenset({Capability.LANE_DETECTOR}))
    ATTACK = Component("constant-offset", lambda p, rng, defense: ConstantOffset(**p), "a 0.5 m MSF offset",
                       params=params_from_signature("constant-offset", ConstantOffset.__init__))
''')
ENTRY_POINTS = textwrap.dedent('''
    [ld3.defenses]
    eager-ld3 = ld3_testplugin:DEFENSE

    [ld3.detectors]
    noisy-oracle = ld3_testplugin:DETECTOR

    [ld3.attacks]
    constant-offset = ld3_testplugin:ATTACK
''')


@pytest.fixture
def plugin_path(tmp_path, monkeypatch):
    (tmp_path / "ld3_testplugin.py").write_text(PLUGIN)
    info = tmp_path / "ld3_testplugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ld3-testplugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    registries = (DEFENSES, DETECTORS, ATTACKS)
    for registry in registries:
        registry.reload_plugins()
    yield tmp_path
    monkeypatch.undo()
    for registry in registries:
        registry.reload_plugins()
    sys.modules.pop("ld3_testplugin", None)


def test_plugin_components_run_end_to_end_under_their_own_names(plugin_path, tmp_path):
    assert "eager-ld3" in DEFENSES and "noisy-oracle" in DETECTORS and "constant-offset" in ATTACKS
    sc = load_scenario("urban-straight").with_overrides(
        duration=12.0, defense="eager-ld3", detector="noisy-oracle", attack={"kind": "constant-offset", "start": 2.0})
    summary = run_scenario(sc, tmp_path / "run").summary
    written = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert written["defense"] == "eager-ld3" and written["detector"] == "noisy-oracle"
    assert written["attack"] == {"kind": "constant-offset", "start": 2.0}
    assert summary["detected"] and 2.0 <= summary["detection_time_s"] < 2.5  # S = 0.5 − 0.2 > τ at once
    assert summary["consequence"] == "stop_in_lane"


def test_plugin_names_reach_the_cli(plugin_path):
    env_path = f"{plugin_path}:{':'.join(p for p in sys.path if p)}"
    out = subprocess.run([sys.executable, "-m", "testbed.cli", "components"], capture_output=True, text=True,
                         check=True, env={"PYTHONPATH": env_path, "PATH": "/usr/bin:/bin"}).stdout
    assert "`eager-ld3`" in out and "`noisy-oracle`" in out and "`constant-offset`" in out
    bad = subprocess.run([sys.executable, "-m", "testbed.cli", "run", "slr", "--detector", "no-such"],
                         capture_output=True, text=True, env={"PYTHONPATH": env_path, "PATH": "/usr/bin:/bin"})
    assert bad.returncode == 2 and "noisy-oracle" in bad.stderr  # the choices listed include the plugin's


def test_unknown_and_clashing_plugins_are_refused(plugin_path):
    info = plugin_path / "ld3_testplugin-0.1.dist-info" / "entry_points.txt"
    info.write_text("[ld3.defenses]\nld3 = ld3_testplugin:DEFENSE\n")
    DEFENSES.reload_plugins()
    with pytest.raises(ValueError, match=re.escape("entry point 'ld3' of ld3.defenses names component 'eager-ld3'")):
        DEFENSES.names()
    info.write_text("[ld3.defenses]\neager-ld3 = ld3_testplugin:ENTRY_THAT_IS_NOT_THERE\n")
    DEFENSES.reload_plugins()
    with pytest.raises(AttributeError):
        DEFENSES.names()
    info.write_text("[ld3.defenses]\neager-ld3 = ld3_testplugin:EagerLd3\n")
    DEFENSES.reload_plugins()
    with pytest.raises(TypeError, match=re.escape("not a testbed.registry.Component")):
        DEFENSES.names()


def test_docs_components_table_is_the_registries_output():
    """docs/components.md is `ld3 components` (with no plugin installed): regenerate it when a component changes."""
    out = subprocess.run([sys.executable, "-m", "testbed.cli", "components"], capture_output=True, text=True,
                         check=True).stdout
    out = "\n".join(line for line in out.splitlines() if not line.startswith("pybullet build time"))
    doc = (Path(__file__).parents[1] / "docs" / "components.md").read_text()
    assert out.strip() in doc, "docs/components.md is stale: regenerate it from `ld3 components`"
