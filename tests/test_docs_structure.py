"""The docs' structure. docs/architecture.md names only what exists: every backticked repository path
(`testbed/loop.py`, `testbed/perception/`) is a file or folder, and every backticked dotted name of a first-party
package (`testbed.loop.ControlLoop.tick`) is a module, or a module's top-level name, or a method of its class.
docs/decisions.md has a contents list of its topics, every topic opens with its current state, and every link
inside it lands on a heading."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from tests.test_import_cycles import first_party_packages, module_files

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"
DECISIONS = ROOT / "docs" / "decisions.md"
TOP_LEVEL = ("tracks", "vehicles", "testbed", "hil", "docs", "tests")


def _backticked(text: str) -> list[str]:
    return re.findall(r"`([^`\s]+)`", text)


def named_paths(text: str) -> list[str]:
    """Backticked repository paths: `DIR/...` for a top-level folder of the repository."""
    return [t for t in _backticked(text) if "/" in t and t.split("/")[0] in TOP_LEVEL]


def named_dotted(text: str, packages: list[str]) -> list[str]:
    """Backticked dotted names that start with a first-party package (`testbed.x.y`)."""
    return [t for t in _backticked(text) if re.fullmatch(r"[A-Za-z_]\w*(\.\w+)+", t) and t.split(".")[0] in packages]


def _defines(body: list[ast.stmt], name: str) -> ast.stmt | None:
    """The statement of `body` that binds `name` at that level (def, class, assignment, import), if any."""
    for stmt in body:
        if isinstance(stmt, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) and stmt.name == name:
            return stmt
        if isinstance(stmt, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in stmt.targets):
            return stmt
        if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name) and stmt.target.id == name:
            return stmt
        if isinstance(stmt, ast.ImportFrom | ast.Import) and any((a.asname or a.name) == name for a in stmt.names):
            return stmt
    return None


def resolves(dotted: str, modules: dict[str, Path]) -> bool:
    """Whether `dotted` is a module, a module's top-level name, or a method (or attribute) of such a class."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        module = ".".join(parts[:cut])
        if module in modules:
            rest = parts[cut:]
            break
    else:
        return False
    body = ast.parse(modules[module].read_text()).body
    for name in rest:
        stmt = _defines(body, name)
        if stmt is None:
            return False
        body = stmt.body if isinstance(stmt, ast.ClassDef) else []
    return True


def test_the_doc_names_the_layers_and_the_paper_algorithms():
    paths = set(named_paths(DOC.read_text()))
    assert {"testbed/loop.py", "testbed/defense/attack_detection.py", "testbed/defense/fusion.py",
            "testbed/attacks/fusionripper.py", "testbed/attacks/stealthy.py", "testbed/attacks/drp.py",
            "testbed/defense/savior.py", "testbed/eval/run/outputs.py"} <= paths
    assert len(paths) > 40


def test_every_path_named_in_the_architecture_doc_exists():
    missing = [p for p in named_paths(DOC.read_text()) if not (ROOT / p).exists()]
    assert not missing, f"docs/architecture.md names paths that do not exist: {missing}"


def test_every_module_named_in_the_architecture_doc_exists():
    packages = first_party_packages()
    modules = module_files(packages)
    named = named_dotted(DOC.read_text(), packages)
    assert "testbed.loop.ControlLoop.tick" in named
    missing = [n for n in named if not resolves(n, modules)]
    assert not missing, f"docs/architecture.md names modules or names that do not exist: {missing}"


def test_the_checks_tell_a_missing_name_from_a_present_one():
    modules = module_files(first_party_packages())
    assert resolves("testbed.control.planner.LanePlanner.start_stop", modules)
    assert not resolves("testbed.control.planner.LanePlanner.no_such_method", modules)
    assert not resolves("testbed.no_such_module", modules)
    assert named_paths("`testbed/x.py` and `ld3.defenses` and `a b`") == ["testbed/x.py"]


def heading_anchor(title: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def _topics(text: str) -> list[tuple[str, str]]:
    """(title, body) of every `## ` section but the contents list."""
    parts = re.split(r"^## ", text, flags=re.M)[1:]
    return [(title, body) for title, _, body in (part.partition("\n") for part in parts) if title != "Contents"]


def test_decisions_lists_every_topic_in_its_contents_in_order():
    text = DECISIONS.read_text()
    contents = text.split("## Contents", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^- \[(.+)\]\(#(.+)\)$", contents, flags=re.M)
    titles = [title for title, _ in _topics(text)]
    assert len(titles) >= 10
    assert listed == [(title, heading_anchor(title)) for title in titles]


def test_every_decisions_topic_opens_with_its_current_state():
    topics = _topics(DECISIONS.read_text())
    late = [title for title, body in topics if not body.lstrip().startswith("**Current state.**")]
    assert not late, f"topics without a current-state lead paragraph: {late}"


def test_every_link_inside_the_decisions_lands_on_a_heading():
    text = DECISIONS.read_text()
    anchors = {heading_anchor(h) for h in re.findall(r"^#+ (.+)$", text, flags=re.M)}
    targets = re.findall(r"\]\(#([^)]+)\)", text.replace("\n", " "))
    assert len(targets) > len(_topics(text))
    assert not [t for t in targets if t not in anchors]


def test_heading_anchors_follow_githubs_rule():
    assert heading_anchor("Detection threshold: the CUSUM's b and τ") == "detection-threshold-the-cusums-b-and-τ"
    assert heading_anchor("The paper command") == "the-paper-command"
