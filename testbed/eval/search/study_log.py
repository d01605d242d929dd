"""A search's journal (`study.log`, Optuna's JSON-lines journal) checked before a search resumes from it: a line
that is not a JSON object (a search killed while writing, a file edited or cut short) is a one-line UserError
naming the file and line, not an exception from inside Optuna."""

from __future__ import annotations

import json
from pathlib import Path

from testbed.errors import UserError


def check_study_log(path: Path) -> None:
    """Refuse `path` (when it exists) unless every line is a JSON object."""
    if not path.exists():
        return
    try:
        lines = path.read_bytes().splitlines()
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    for number, line in enumerate(lines, start=1):
        try:
            ok = isinstance(json.loads(line), dict)
        except ValueError:
            ok = False
        if not ok:
            last = " (the last line: a search killed while writing it)" if number == len(lines) else ""
            raise UserError(f"{path}:{number}: not a line of the search's journal{last}; remove that line to resume "
                            f"from the trials before it, or choose another --out")
