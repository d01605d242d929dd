import math

import pytest

from testbed.eval.run.outputs import TRAJECTORY_COLUMNS, read_trajectory


def test_trajectory_reader_gives_floats_with_nan_for_empty_cells(tmp_path):
    header = ",".join(TRAJECTORY_COLUMNS)
    rows = ["0.000000,0,0,0,0,0.010000,0.020000,,,normal,0,0,,", "0.010000,0,0,0,0,0.030000,,0.5,0.1,ar,0,0,,"]
    (tmp_path / "trajectory.csv").write_text("\n".join([header, *rows]) + "\n")
    cols = read_trajectory(tmp_path, ("t", "phys_dev", "msf_dev", "ld_dev"))
    assert cols["t"].tolist() == [0.0, 0.01]
    assert cols["phys_dev"].tolist() == [0.01, 0.03]
    assert cols["msf_dev"][0] == 0.02 and math.isnan(cols["msf_dev"][1])
    assert math.isnan(cols["ld_dev"][0]) and cols["ld_dev"][1] == 0.5
    with pytest.raises(ValueError, match="no column"):
        read_trajectory(tmp_path, ("t", "lateral"))
