"""One bad or hostile input to `ld3`: an argv (with `{ws}` for the workspace), the files and links it needs, and a
piece of the one line it must be refused with."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

Content = str | bytes | Callable[[], bytes]
"""A file's content; a callable builds it when the workspace is made (checkpoints and shards need torch, numpy)."""


@dataclass(frozen=True)
class Case:
    id: str
    argv: tuple[str, ...]
    says: str
    """A piece of the one-line refusal (case-insensitive)."""
    files: dict[str, Content] = field(default_factory=dict)
    """Files to create in the workspace first (path -> content)."""
    links: dict[str, str] = field(default_factory=dict)
    """Symbolic links to create in the workspace (path -> target)."""


def make_files(root: Path, files: dict[str, Content], links: dict[str, str] | None = None) -> None:
    """Write `files` (and `links`) under `root`."""
    for name, content in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        data = content() if callable(content) else content
        if isinstance(data, bytes):
            path.write_bytes(data)
        else:
            path.write_text(data)
    for name, target in (links or {}).items():
        (root / name).symlink_to(target)
