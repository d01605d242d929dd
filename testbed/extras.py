"""The optional extras of the install and the modules each brings, so that a command missing one names the
`pip install` that fixes it before it opens a bus or builds a world."""

from __future__ import annotations

import importlib.util
from collections.abc import Iterable

from testbed.errors import UserError

EXTRA_OF_MODULE = {"torch": "nn", "cv2": "camera", "onnxruntime": "onnx", "mcap": "record", "pybullet": "sim",
                   "matplotlib": "sim", "gymnasium": "gym", "ray": "ray"}


def install_hint(extra: str) -> str:
    return f"pip install 'ld3-testbed[{extra}]'"


def missing_extra(exc: ModuleNotFoundError, what: str) -> UserError:
    """The one-line error for `what` failing on the missing module of `exc`."""
    extra = EXTRA_OF_MODULE.get((exc.name or "").partition(".")[0])
    fix = install_hint(extra) if extra is not None else "install it"
    return UserError(f"{what} needs the {exc.name} module, which is not installed: {fix}")


def require_modules(modules: Iterable[str], extra: str, what: str) -> None:
    """UserError naming `extra` unless every module in `modules` can be imported."""
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise UserError(f"{what} needs {', '.join(missing)}, which is not installed: {install_hint(extra)}")
