"""The compiled per-tick kernels (Cython extension modules built at install where a C compiler is present).

`compiled_module(name)` imports one of them, or returns None where it was not built or the environment
variable `LD3_COMPILED` is `0`; the caller then keeps its pure-Python path, which stays the reference every
kernel is tested equal to.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType


def compiled_module(name: str) -> ModuleType | None:
    """The extension module `name`, or None (not built, or switched off by LD3_COMPILED=0)."""
    if os.environ.get("LD3_COMPILED", "1") == "0":
        return None
    try:
        return importlib.import_module(name)
    except ImportError:
        return None
