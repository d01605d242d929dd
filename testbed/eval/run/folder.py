"""The one way every command writes its output, all or nothing: a folder is written into a hidden sibling and
renamed into place, a file into a hidden sibling file and renamed over its name, so a killed or failed command
never leaves half an output and never mixes with an earlier one. A folder holding the command's own earlier
output (its `marker` file) is replaced only when asked (`force`), a folder with anything else never; the earlier
output stays until the new one is complete.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from testbed.errors import UserError

SUMMARY = "summary.json"
TMP_MARK = ".tmp-"


def check_out_dir(out: Path, force: bool, marker: str = SUMMARY, what: str = "a run", can_force: bool = True) -> None:
    """A one-line UserError when `out` cannot take a new output: a file, a finished output (holding `marker`)
    without `force` (`can_force`: the command has a --force to say so), or a folder with other content."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} is a file, not a folder; choose a folder")
    try:
        empty = not out.exists() or not any(out.iterdir())
    except OSError as exc:
        raise UserError(f"cannot read output directory {out}: {exc.strerror}") from None
    if empty:
        return
    if not (out / marker).is_file():
        raise UserError(f"--out {out} holds files that are not {what}; choose a new or empty folder")
    if not force:
        replace = "pass --force to replace it, or " if can_force else ""
        raise UserError(f"--out {out} holds a finished {what.removeprefix('a ')}; {replace}choose another folder")


def _alive(pid_text: str) -> bool:
    """Whether the process `pid_text` names still runs (False for text that is no process id)."""
    try:
        os.kill(int(pid_text), 0)
    except (ValueError, ProcessLookupError):
        return False
    except PermissionError:  # another user's process
        return True
    return True


@contextmanager
def claimed_out_dir(out: Path, force: bool) -> Iterator[Path]:
    """`out` as an empty folder for a run that writes in place as it goes (a CAN log, a vehicle drive), for the
    body that runs it: refused as `check_out_dir` refuses; with `force` a finished run there is moved aside and
    removed only once the body returns; if the body raises, the new folder goes and the earlier run comes back.
    An earlier run set aside by a command that was killed (`kill -9`) is named, never overwritten."""
    for stale in sorted(out.parent.glob(f".{out.name}.old-*")):
        if not _alive(stale.name.rpartition("-")[2]):
            raise UserError(f"an earlier run of --out {out} was set aside by a command that died before it finished: "
                            f"it is in {stale}; move it back to {out} or remove it, then start again")
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
def output_folder(out: Path, force: bool = False, marker: str = SUMMARY, what: str = "a run",
                  can_force: bool = True) -> Iterator[Path]:
    """Yield a fresh temporary folder beside `out`; when the body returns, it becomes `out` (an earlier output
    there is removed only then); when the body raises (or is interrupted), it is removed and `out` is left as
    it was. Refused as `check_out_dir` refuses."""
    check_out_dir(out, force, marker, what, can_force)
    tmp = out.parent / f".{out.name}{TMP_MARK}{os.getpid()}"
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


def run_folder(out: Path, force: bool = False):
    """`output_folder` for one run: its marker is summary.json."""
    return output_folder(out, force)


@contextmanager
def output_file(path: Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary file name beside `path` (with `path`'s suffix, so writers that go by the name write the
    same format); when the body returns it is renamed over `path`, when it raises it is removed. A `path` that is
    a folder or a device, or (given `suffix`) has another suffix, is refused before anything is written."""
    if suffix is not None and path.suffix.lower() != suffix:
        raise UserError(f"--out {path}: the file name must end in {suffix}")
    if path.is_symlink() or (path.exists() and not path.is_file()):
        raise UserError(f"--out {path} is not a regular file; choose a file name")
    if not path.parent.is_dir():
        raise UserError(f"--out {path}: its folder {path.parent} is missing (no such file or directory)")
    tmp = path.parent / f".{path.stem}{TMP_MARK}{os.getpid()}{path.suffix}"
    try:
        yield tmp
        try:
            os.replace(tmp, path)
        except OSError as exc:
            raise UserError(f"cannot write {path}: {exc.strerror}") from None
    finally:
        tmp.unlink(missing_ok=True)
