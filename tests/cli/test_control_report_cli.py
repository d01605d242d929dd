"""`ld3 control report` refuses bad input in one line (exit 2) before any analysis."""

from __future__ import annotations

import pytest

from testbed.cli import main


@pytest.mark.parametrize(("argv", "message"), [
    (["--rates", "forty"], "--rates"),
    (["--rates", "0.5"], "not a control rate"),
    (["--vehicle", "tank"], "unknown vehicle 'tank'"),
    (["--steer-rate-weight", "-1"], "--steer-rate-weight"),
])
def test_bad_input_is_one_line(tmp_path, capsys, argv, message) -> None:
    assert main(["control", "report", *argv, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not (tmp_path / "r").exists()
