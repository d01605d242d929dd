"""A file the reader cannot use is one line naming the file, the element and why (a UserError at the registry)."""

from __future__ import annotations

import pytest

from testbed.cli import main
from testbed.errors import UserError
from testbed.presets import TrackFileError, build_track
from tests.tracks.opendrive.xodr_text import constant, document, geometry, road, section

LANES = [section(0.0, [constant(3.5)])]
TWO_WAY = [section(0.0, [constant(3.5)], [constant(3.5)])]
LINE = [geometry(0, 0.0, 0.0, 0.0, 50.0, "<line/>")]
APART = document(road("1", 50.0, LINE, LANES), road("2", 50.0, [geometry(0, 0.0, 30.0, 0.0, 50.0, "<line/>")], LANES))


@pytest.mark.parametrize(("text", "route", "message"), [
    (None, "", "file: not found"),
    ("this is not <xml", "", "file: not XML"),
    (document(road("4", 50.0, [geometry(0, 0.0, 0.0, 0.0, 50.0, '<clothoid k="1"/>')], LANES)), "",
     "road 4 <geometry s=0>: unsupported geometry <clothoid> (supported: line, arc, spiral, poly3, paramPoly3)"),
    (APART, "#1,2", "route 1,2: road 1 does not lead to road 2 (no road link or junction connection joins them)"),
    (APART, "#1,9", "route 1,9: road '9' is not in the file"),
    (APART, "#2,2", "route 2,2: road 2 is named twice in a row"),
    (document(road("1", 50.0, [geometry(0, 0.0, "x", 0.0, 50.0, "<line/>")], LANES)), "",
     "road 1 <geometry s=0>: attribute y='x' is not a number"),
    (document(road("1", 50.0, LINE, LANES), minor=3), "", "<header>: OpenDRIVE 1.3 is not supported (1.4 to 1.8 are)"),
    (document(road("1", 50.0, LINE, [TWO_WAY[0].replace('"driving"', '"sidewalk"')])), "",
     "road 1 <laneSection s=0>: no drivable lane in the driving direction"),
    (document(road("1", 50.0, LINE, TWO_WAY)), "#@-3", "road 1 <laneSection s=0>: lane -3 is not a drivable lane of "
     "the driving direction (those are: -1)"),
    (document(road("1", 50.0, LINE, [section(0.0, [constant(3.5)]).replace("<width", "<border")])), "",
     "lane -1: <border> is not supported (describe the lane by <width>)"),
])
def test_an_unusable_file_is_one_line_naming_the_element(text, route, message, tmp_path):
    path = tmp_path / "bad.xodr"
    if text is not None:
        path.write_text(text)
    with pytest.raises(TrackFileError) as info:
        build_track(f"xodr:{path}{route}")
    assert isinstance(info.value, UserError)
    assert str(info.value).startswith(f"{path}: ") and message in str(info.value)
    assert "\n" not in str(info.value)


def test_the_cli_prints_the_line_and_exits_2(tmp_path, capsys):
    assert main(["tracks", "show", f"xodr:{tmp_path / 'none.xodr'}"]) == 2
    err = capsys.readouterr().err
    assert err == f"ld3: error: {tmp_path / 'none.xodr'}: file: not found\n"
