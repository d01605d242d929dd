"""The Python API and the Gymnasium environment: stepping, custom components, the docs' worked scripts."""

import math
import subprocess
import sys
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import testbed.gym_env  # noqa: F401 - registers ld3/Lateral-v0
from testbed import api
from testbed.eval.run.outputs import TRAJECTORY_COLUMNS
from testbed.rates import CONTROL_HZ

EXAMPLES = sorted((Path(__file__).parents[1] / "docs" / "examples").glob("*.py"))


def test_stepping_matches_running_to_the_end(tmp_path):
    sc = api.scenario("urban-straight", duration=14.0, localization="msf", defense="ld3",
                      attack={"kind": "trace", "trace": "default", "start": 5.0})
    whole = api.run(sc)
    with api.Simulation(sc) as sim:
        first_ar = None
        while not sim.done:
            rec = sim.step()
            if rec.mode == "ar" and first_ar is None:
                first_ar = rec.t
        stepped = sim.result()
        sim.write(tmp_path)
    assert list(whole.frame.columns) == list(TRAJECTORY_COLUMNS)
    assert whole.frame.equals(stepped.frame) and len(whole.frame) == len(stepped.frame) > 100
    assert first_ar == pytest.approx(whole.summary["detection_time_s"])
    assert (tmp_path / "summary.json").exists() and (tmp_path / "trajectory.csv").exists()
    with pytest.raises(RuntimeError, match="over"):
        sim.step()


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_docs_worked_scripts_run(script, tmp_path):
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip()
    if script.stem == "sweep_b":
        rows = (tmp_path / "runs" / "sweep-b" / "runs.csv").read_text().splitlines()
        assert rows[0].startswith("b,") and [r.split(",")[0] for r in rows[1:]] == ["0.4", "0.6", "0.8"]
    if script.stem == "custom_defense":
        assert "gentle-ld3: stop_in_lane" in done.stdout


def test_gym_environment_follows_the_api_and_ends_with_the_run():
    env = gymnasium.make("ld3/Lateral-v0", scenario_name="urban-straight", duration=3.0, ticks_per_step=20)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=4)
    assert env.observation_space.contains(obs) and obs[3] == 0.0
    steps, info, done = 0, {}, False
    while not done:
        obs, reward, done, truncated, info = env.step(np.array([0.5], dtype=np.float32))
        steps += 1
        assert reward >= 0.0 and not truncated and obs[3] == pytest.approx(0.5)
    assert steps == math.ceil((round(3.0 * CONTROL_HZ) - 1) / 20)  # 20 ticks a step (the first ran in reset)
    assert info["summary"]["attack"] == {"kind": "policy"} and info["summary"]["sim_time_s"] == pytest.approx(3.0)
    env.close()
    default = gymnasium.make("ld3/Lateral-v0", scenario_name="urban-straight", duration=3.0)
    assert default.unwrapped.ticks_per_step == round(0.1 * CONTROL_HZ)  # one 10 Hz GNSS fix a step
