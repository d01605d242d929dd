"""No import cycle among the first-party packages (those `pyproject.toml` packages), read from the source.

The graph has one node per module and an edge for every import of a first-party module anywhere in a module:
at module level and inside functions and methods alike, since a deferred import still ties the two modules
together (it only hides the cycle until the function runs). Imports under `if TYPE_CHECKING:` are left out
of the layers' check (they never run) but count for cycles: two modules that name each other's types are one
concern split in two. `from package import name` is an edge to the submodule `package.name` when there is one, else
to the package itself. An import of `a.b.c` is an edge to `a.b.c` only, not to the packages `a` and `a.b` whose
`__init__` it also runs: a package that re-exports its own submodules is safe as long as none of them imports
that package back, and such an import is an edge to the package here, so it is caught.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def first_party_packages() -> list[str]:
    """The top-level packages setuptools installs (`[tool.setuptools.packages.find] include`)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["packages"]["find"]["include"]
    return sorted({p.split(".")[0].rstrip("*") for p in patterns})


def module_files(packages: list[str]) -> dict[str, Path]:
    """Dotted module name → source file, for every module of `packages` (a package is its `__init__`)."""
    modules = {}
    for package in packages:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(node: ast.AST, type_checking: bool = False) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement under `node`, skipping the bodies of `if TYPE_CHECKING:` unless `type_checking`."""
    found = []
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.If) and _is_type_checking(child.test) and not type_checking:
            for other in child.orelse:
                found += _imports_in(other, type_checking)
            continue
        found += _imports_in(child, type_checking)
    return found


def _imports_in(node: ast.AST, type_checking: bool) -> list[ast.Import | ast.ImportFrom]:
    return [node] if isinstance(node, ast.Import | ast.ImportFrom) else _imports(node, type_checking)


def import_graph(modules: dict[str, Path], type_checking: bool = False) -> dict[str, set[str]]:
    """Module → the first-party modules it imports (see the module docstring); with `type_checking`, the imports
    under `if TYPE_CHECKING:` too."""
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        edges: set[str] = set()
        for imp in _imports(ast.parse(path.read_text(), str(path)), type_checking):
            if isinstance(imp, ast.Import):
                edges |= {alias.name for alias in imp.names if alias.name in modules}
                continue
            base = imp.module or ""
            if imp.level:
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[:len(anchor) - (imp.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in imp.names:
                target = f"{base}.{alias.name}"
                if target in modules:
                    edges.add(target)
                elif base in modules:
                    edges.add(base)
        edges.discard(name)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of `graph` as [a, b, ..., a], or None; depth-first, in sorted order (a stable answer)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: finished
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_the_graph_sees_every_kind_of_import():
    graph = import_graph(module_files(first_party_packages()))
    assert {"testbed", "hil", "tracks", "vehicles"} <= {name.split(".")[0] for name in graph}
    assert "testbed.eval.campaign.backend" in graph["testbed.eval.campaign.ray_backend"]  # module level
    assert "testbed.eval.run.runner" in graph["testbed.eval.campaign.driver"]  # inside a function
    assert "testbed.defense.ld3" in graph["testbed.defense"]  # a package's re-export


def test_a_cycle_is_found_and_named():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_type_checking_imports_and_relative_imports_are_read_as_python_runs_them(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("from .a import x\n")
    (pkg / "a.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import b\n"
                              "else:\n    import pkg.c\nx = 1\n")
    (pkg / "b.py").write_text("def f():\n    from . import a\n")
    (pkg / "c.py").write_text("")
    modules = {"pkg": pkg / "__init__.py", **{f"pkg.{m}": pkg / f"{m}.py" for m in "abc"}}
    assert import_graph(modules) == {"pkg": {"pkg.a"}, "pkg.a": {"pkg.c"}, "pkg.b": {"pkg.a"}, "pkg.c": set()}
    assert import_graph(modules, type_checking=True)["pkg.a"] == {"pkg.b", "pkg.c"}
    assert find_cycle(import_graph(modules, type_checking=True)) == ["pkg.a", "pkg.b", "pkg.a"]


def test_the_camera_renders_a_scene_without_importing_the_world():
    graph = import_graph(module_files(first_party_packages()), type_checking=True)
    assert "testbed.world" not in graph["testbed.camera"], "testbed/camera.py renders a RenderScene, not the world"


def test_no_import_cycle_among_the_first_party_packages():
    cycle = find_cycle(import_graph(module_files(first_party_packages()), type_checking=True))
    assert cycle is None, "import cycle (type-checking imports included): " + " -> ".join(cycle or [])


LAYERS: dict[str, int] = {
    # 0 geometry and the car: know nothing of testbed
    "tracks": 0, "vehicles": 0,
    # 1 the core a chassis computer runs (no PyBullet, no torch): contracts, localization, defense, control, loop
    "testbed": 1, "testbed.errors": 1, "testbed.registry": 1, "testbed.params": 1, "testbed.rates": 1,
    "testbed.lane_detection": 1, "testbed.lane_tracker": 1, "testbed.localization": 1, "testbed.defense": 1,
    "testbed.control": 1, "testbed.attacks": 1, "testbed.chassis": 1, "testbed.loop": 1, "testbed.assembly": 1,
    "testbed.presets": 1, "testbed.extras": 1,
    # 2 the simulation: world, camera, the run-time lane detectors, traffic
    "testbed.world": 2, "testbed.ground": 2, "testbed.camera": 2, "testbed.tiny_boxes": 2, "testbed.conditions": 2,
    "testbed.perception": 2, "testbed.traffic": 2, "testbed.direct_chassis": 2,
    # 3 one run (scenario, build, runner, summary, outputs), the CAN link and the vehicle beside it, and the lane
    # detectors' training
    "testbed.eval.run": 3, "testbed.perception.training": 3, "hil": 3, "hil.link": 3, "hil.vehicle": 3,
    # 4 many runs: campaigns and their backends, the search, reports, the paper's experiments, analysis; the ECU
    # emulator's scenarios and drills; the lane detectors' lab drives; the Python API
    "testbed.eval": 4, "testbed.eval.campaign": 4, "testbed.eval.search": 4, "testbed.eval.report": 4,
    "testbed.eval.experiments": 4, "testbed.eval.analysis": 4, "hil.emulator": 4, "testbed.perception.lab": 4,
    "testbed.api": 4, "testbed.gym_env": 4,
    # 5 the commands
    "testbed.cli": 5, "testbed.perception.commands": 5, "hil.cli": 5, "hil.vehicle_cli": 5, "hil.replay_cli": 5,
    "hil.detect_cli": 5, "hil.__main__": 5,
}
"""Module prefix -> layer (the longest prefix decides); a module imports only from its own layer or lower ones."""

def layer_of(module: str, layers: dict[str, int]) -> int:
    prefix = max((p for p in layers if module == p or module.startswith(p + ".")), key=len, default=None)
    assert prefix is not None, f"{module} has no layer: add its package to LAYERS"
    return layers[prefix]


def upward_imports(graph: dict[str, set[str]], layers: dict[str, int]) -> set[tuple[str, str]]:
    """(importer, imported) for every import of a module from a higher layer."""
    return {(m, e) for m, edges in graph.items() for e in edges if layer_of(e, layers) > layer_of(m, layers)}


def test_an_upward_import_is_found():
    graph = {"low.a": {"high.b"}, "high.b": {"low.c"}, "low.c": set()}
    assert upward_imports(graph, {"low": 0, "high": 1}) == {("low.a", "high.b")}


def test_no_import_runs_up_the_layers():
    found = sorted(upward_imports(import_graph(module_files(first_party_packages())), LAYERS))
    assert not found, "imports from a higher layer (see docs/architecture.md): " + ", ".join(f"{a} -> {b}"
                                                                                              for a, b in found)
