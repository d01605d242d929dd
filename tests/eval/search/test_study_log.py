"""A search's journal is checked before a resume reads it: a cut-short or garbled line is one UserError naming
the file and line; a whole journal passes."""

from __future__ import annotations

import pytest

from testbed.errors import UserError
from testbed.eval.search.study_log import check_study_log

LINE = '{"op_code":0,"worker_id":"w","study_name":"search","directions":[2]}\n'


def test_a_whole_journal_and_a_missing_one_pass(tmp_path):
    (tmp_path / "study.log").write_text(LINE * 3)
    check_study_log(tmp_path / "study.log")
    check_study_log(tmp_path / "none.log")


@pytest.mark.parametrize(("text", "where"), [(LINE * 2 + LINE[:30], ":3: "), (LINE + "[1, 2]\n" + LINE, ":2: "),
                                             (LINE + "\x00\xff\n", ":2: ")])
def test_a_cut_short_or_garbled_line_is_named(tmp_path, text, where):
    (tmp_path / "study.log").write_text(text)
    with pytest.raises(UserError, match=where):
        check_study_log(tmp_path / "study.log")
