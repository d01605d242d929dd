"""Every bad or hostile input in the table is refused the same way: a nonzero exit (2, or 4 for a CAN link
that cannot be opened), exactly one line on stderr that names the problem, no traceback, no internal error,
nothing written anywhere in the workspace or the working folder, and the finished run already there intact."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from testbed.cli import main
from tests.cli.bad_inputs import CASES
from tests.cli.case import Case, make_files

PREVIOUS_RUN = {"summary.json": '{"scenario": "earlier"}', "trajectory.csv": "t\n0.0\n", "birdseye.png": "png"}
FOREIGN = {"notes.txt": "mine", "slr-0/keep.txt": "a folder named like a run id"}


def _snapshot(root: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None) for p in sorted(root.rglob("*"))}


def _workspace(root: Path, case: Case) -> None:
    make_files(root, {**{f"prev/{k}": v for k, v in PREVIOUS_RUN.items()},
                      **{f"foreign/{k}": v for k, v in FOREIGN.items()}, "afile": "keep", **case.files}, case.links)


def test_the_table_covers_every_subcommand_with_over_a_hundred_cases():
    from testbed.cli import build_parser

    commands = {c.argv[0] for c in CASES}
    sub = next(a for a in build_parser()._actions if a.dest == "cmd")
    assert len(CASES) >= 100 and len({c.id for c in CASES}) == len(CASES)
    assert set(sub.choices) - {"scenarios", "components"} <= commands  # those two take no input


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_refused_in_one_line_and_touches_nothing(case, tmp_path, monkeypatch):
    ws, cwd = tmp_path / "ws", tmp_path / "cwd"
    cwd.mkdir()
    _workspace(ws, case)
    monkeypatch.chdir(cwd)
    before = _snapshot(tmp_path)
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main([arg.replace("{ws}", str(ws)) for arg in case.argv])
        except SystemExit as exc:
            code = exc.code
    lines = [line for line in err.getvalue().splitlines() if line.strip()]
    assert code in (2, 4), (code, err.getvalue(), out.getvalue())
    assert len(lines) == 1 and "Traceback" not in err.getvalue() and "internal error" not in lines[0], lines
    assert case.says.lower() in lines[0].lower(), lines[0]
    assert _snapshot(tmp_path) == before
