"""The Python API: build a scenario, run it to the end or step it tick by tick, with your own defense,
lane detector or attack objects in place of the scenario's; results as a pandas DataFrame (one row per
control tick, trajectory.csv's columns) plus the summary dict. docs/api.md has worked scripts.

    from testbed import api
    sc = api.scenario("local", attack={"kind": "fusionripper", "d": 1.0, "f": 1.5, "start": 15.0},
                      localization="msf", defense="ld3")
    result = api.run(sc)                       # or: with api.Simulation(sc) as sim: ... sim.step() ...
    result.frame.plot(x="t", y=["phys_dev", "msf_dev"])
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from testbed.attacks.base import Attack
from testbed.defense.base import Defense
from testbed.eval.run.outputs import TRAJECTORY_COLUMNS
from testbed.eval.run.runner import RunResult, SimRun, prepare_out_dir
from testbed.eval.run.scenario import Scenario, load_scenario
from testbed.lane_detection import LaneDetector
from testbed.loop import TickRecord

__all__ = ["Result", "Scenario", "Simulation", "run", "scenario"]


def scenario(name_or_path: str = "urban-straight", **overrides: Any) -> Scenario:
    """A shipped scenario by name, or a TOML file, with fields replaced (`defense_params` and `attack` as
    dicts, exactly as the TOML tables); validated."""
    return load_scenario(name_or_path).with_overrides(**overrides)


@dataclass(frozen=True)
class Result:
    """A run's summary (summary.json's content) and its ticks as a DataFrame."""

    summary: dict[str, Any]
    frame: pd.DataFrame


def _frame(rows: list[TickRecord]) -> pd.DataFrame:
    return pd.DataFrame([dataclasses.astuple(r) for r in rows],
                        columns=[f.name for f in dataclasses.fields(TickRecord)])[list(TRAJECTORY_COLUMNS)]


class Simulation:
    """One run you can step: `step()` one control tick at a time until `done`, or `run()` to the end;
    `write(dir)` writes the output contract of what has run. Close it (or use `with`) to free PyBullet."""

    def __init__(self, sc: Scenario, *, defense: Defense | None = None, detector: LaneDetector | None = None,
                 attack: Attack | list[Attack] | None = None, render: bool | None = None,
                 video: bool = False) -> None:
        self.scenario = sc
        self._sim = SimRun(sc, render=render, video=video, defense=defense, detector=detector, attack=attack)

    @property
    def done(self) -> bool:
        return self._sim.done

    @property
    def defense(self) -> Defense:
        return self._sim.parts.defense

    @property
    def attack(self) -> Attack | None:
        return self._sim.parts.attack

    def step(self) -> TickRecord:
        """One control tick (100 Hz by default): the record trajectory.csv gets for it."""
        return self._sim.step()

    def run(self, progress: bool = False) -> Result:
        """Step until the run is over and return its result."""
        return self._result(self._sim.run(progress=progress))

    def result(self) -> Result:
        """The result of the ticks run so far."""
        return self._result(self._sim.result())

    def write(self, out_dir: Path | str) -> None:
        """summary.json, trajectory.csv and the figures of the ticks run so far into `out_dir`."""
        out = Path(out_dir)
        prepare_out_dir(out)
        self._sim.write_outputs(out, self._sim.result())

    @staticmethod
    def _result(raw: RunResult) -> Result:
        return Result(raw.summary, _frame(raw.rows))

    def close(self) -> None:
        self._sim.close()

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run(sc: Scenario, out: Path | str | None = None, *, defense: Defense | None = None,
        detector: LaneDetector | None = None, attack: Attack | list[Attack] | None = None,
        progress: bool = False) -> Result:
    """Run `sc` to the end (with your own components where given); write its outputs to `out` when given."""
    with Simulation(sc, defense=defense, detector=detector, attack=attack) as sim:
        result = sim.run(progress=progress)
        if out is not None:
            sim.write(out)
        return result
