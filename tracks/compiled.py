"""The compiled per-tick kernels (Cython extension modules built at install where a C compiler is present).

`compiled_module(name)` imports one of them, or returns None where it was not built, where it is older than its
source (a checkout updated without rebuilding: it says so once, on stderr), or where the environment variable
`LD3_COMPILED` is `0`; the caller then keeps its pure-Python path, which stays the reference every kernel is
tested equal to.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from pathlib import Path
from types import ModuleType

_EXTERN = re.compile(r'^cdef extern from "([^"]+)"', re.MULTILINE)


def kernel_sources(built: Path) -> list[Path]:
    """The sources a built kernel was compiled from, where they sit beside it: its `.pyx`, its `.pxd` and the
    headers the `.pyx` names in `cdef extern from`."""
    stem = built.name.split(".", 1)[0]
    pyx = built.with_name(stem + ".pyx")
    if not pyx.is_file():
        return []
    named = [built.with_name(h) for h in _EXTERN.findall(pyx.read_text(encoding="utf-8"))]
    return [p for p in (pyx, built.with_name(stem + ".pxd"), *named) if p.is_file()]


def stale_source(module: ModuleType) -> Path | None:
    """A source file newer than the module's built file, or None."""
    built = Path(module.__file__ or "")
    if not built.is_file():
        return None
    when = built.stat().st_mtime
    return next((p for p in kernel_sources(built) if p.stat().st_mtime > when), None)


def compiled_module(name: str) -> ModuleType | None:
    """The extension module `name`, or None (not built, stale, or switched off by LD3_COMPILED=0)."""
    if os.environ.get("LD3_COMPILED", "1") == "0":
        return None
    try:
        module = importlib.import_module(name)
    except ImportError:
        return None
    newer = stale_source(module)
    if newer is not None:
        print(f"ld3: the compiled kernel {name} is older than {newer.name}; using the Python reference "
              "(rebuild with `make test` or `python setup.py build_ext --inplace`)", file=sys.stderr)
        return None
    return module
