"""A run's output folder, written all or nothing: the run writes into a hidden sibling and the finished
folder is renamed into place, so a killed or failed run never leaves a half-written folder and never mixes
with an earlier run; a finished run is replaced only when asked (`force`), a folder that is not a run never."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from testbed.errors import UserError

SUMMARY = "summary.json"


def check_out_dir(out: Path, force: bool) -> None:
    """A one-line UserError when `out` cannot take a new run: a file, a finished run without `force`, or a
    folder with other content."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} is a file, not a folder; choose a folder")
    if not out.exists() or not any(out.iterdir()):
        return
    if not (out / SUMMARY).is_file():
        raise UserError(f"--out {out} holds files that are not a run; choose a new or empty folder")
    if not force:
        raise UserError(f"--out {out} holds a finished run; pass --force to replace it, or choose another folder")


@contextmanager
def claimed_out_dir(out: Path, force: bool) -> Iterator[Path]:
    """`out` as an empty folder for a run that writes in place as it goes (a CAN log, a vehicle drive), for
    the body that starts the run: refused as `check_out_dir` refuses; with `force` a finished run there is moved
    aside and removed only once the body returns; if the body raises, the new folder goes and the earlier run
    comes back."""
    check_out_dir(out, force)
    old = out.parent / f".{out.name}.old-{os.getpid()}"
    moved = (out / SUMMARY).is_file()
    try:
        if moved:
            shutil.rmtree(old, ignore_errors=True)
            os.rename(out, old)
        created = not out.exists()
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot write to output directory {out}: {exc.strerror}") from None
    try:
        yield out
    except BaseException:
        if created:
            shutil.rmtree(out, ignore_errors=True)
        if moved:
            os.rename(old, out)
        raise
    shutil.rmtree(old, ignore_errors=True)


@contextmanager
def run_folder(out: Path, force: bool = False) -> Iterator[Path]:
    """Yield a fresh temporary folder beside `out`; when the body returns, it becomes `out` (an earlier run
    there is removed only then); when the body raises, it is removed and `out` is left as it was."""
    check_out_dir(out, force)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
    except OSError as exc:
        raise UserError(f"cannot write to output directory {out}: {exc.strerror}") from None
    try:
        yield tmp
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        if out.exists():
            os.rename(out, old)
        os.rename(tmp, out)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
