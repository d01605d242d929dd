"""One registry per component family (docs/architecture.md, "Registries"), in the style of python-can's
interface registry.

A registry holds the built-in components of its family and, on first lookup, those that installed
packages declare under the family's entry-point group (`ld3.defenses`, `ld3.detectors`, `ld3.attacks`,
`ld3.campaigns`, `ld3.campaign_backends`); an entry point names an entry of the family's kind (a `Component`,
a campaign spec, a campaign backend). CLI choices and help, scenario validation and the docs table are read
from the registry, so a component added in one place is usable everywhere.

A component declares what it `needs` from the run instead of being switched on by name; the run checks
those needs against what its configuration provides (`Capability`) and refuses, naming the fix, a
component that could not act.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from enum import StrEnum
from importlib.metadata import entry_points
from typing import Any, Generic, Protocol, TypeVar

from testbed.errors import UserError
from testbed.params import Params, validate_params


class Capability(StrEnum):
    """What a run's configuration provides and a component may need."""

    LANE_DETECTOR = "lane_detector"
    """Lane detections reach the defense (any detector but `none`)."""
    CAMERA_IMAGE = "camera_image"
    """The detector reads rendered camera frames (so a painted road patch is seen)."""
    GNSS = "gnss"
    """The localization fuses GNSS fixes (the MSF), so spoofed fixes move the pose."""


FIXES: dict[Capability, str] = {
    Capability.LANE_DETECTOR: "a lane detector: use --detector neural, classical or oracle",
    Capability.CAMERA_IMAGE: "a detector that reads the camera: use --detector neural or classical",
    Capability.GNSS: "a localization that fuses GNSS: use --localization msf",
}


class NoParams(Params):
    """The parameters of a component that has none."""


class UnknownComponent(UserError):
    """A name that no built-in component and no installed plugin of the family has."""


@dataclass(frozen=True)
class Component:
    """A named component: how to build it (a family-specific factory), one line of help, what it needs and
    provides, its own parameters (`params`, a `Params` model of its scenario table), and for defenses that share a
    model, the keys of it they `reads` (empty: all of them)."""

    name: str
    factory: Callable[..., Any]
    help: str
    needs: frozenset[Capability] = frozenset()
    provides: frozenset[Capability] = frozenset()
    params: type[Params] = NoParams
    reads: frozenset[str] = frozenset()
    capabilities: frozenset[str] = frozenset()
    """For attacks: the threat capabilities it acts through (`testbed.attacks.threat`)."""
    space: tuple[Any, ...] = ()
    """For attacks: the dimensions a worst-case search varies (`testbed.attacks.space`); empty: not searched."""

    def settings(self, table: Mapping[str, Any], where: str) -> Params:
        """This component's parameters from `table` (validated; ParamsError names the key)."""
        return validate_params(self.params, table, where)


class Entry(Protocol):
    """What a registry holds: a name, one line of help, and what it needs from the run."""

    name: str
    help: str
    needs: frozenset[Capability]


E = TypeVar("E", bound=Entry)


class Registry(Generic[E]):
    """The entries of one family (instances of `kind`): built-ins first, then the entry points of `group`,
    loaded once."""

    def __init__(self, family: str, kind: type[E], group: str | None = None) -> None:
        self.family = family
        self.kind = kind
        self.group = group
        self._builtin: dict[str, E] = {}
        self._plugins: dict[str, E] | None = None

    def add(self, component: E) -> E:
        """Register a built-in component."""
        if component.name in self._builtin:
            raise ValueError(f"{self.family} {component.name!r} registered twice")
        self._builtin[component.name] = component
        return component

    def _all(self) -> dict[str, E]:
        if self._plugins is None:
            self._plugins = self._load_plugins()
        return {**self._builtin, **self._plugins}

    def _load_plugins(self) -> dict[str, E]:
        if self.group is None:
            return {}
        found: dict[str, E] = {}
        for ep in entry_points(group=self.group):
            component = ep.load()
            if not isinstance(component, self.kind):
                raise TypeError(f"entry point {ep.name!r} of {self.group} is a {type(component).__name__}, "
                                f"not a {self.kind.__module__}.{self.kind.__name__}")
            if component.name != ep.name:
                raise ValueError(f"entry point {ep.name!r} of {self.group} names component {component.name!r}")
            if component.name in self._builtin or component.name in found:
                raise ValueError(f"{self.family} {component.name!r} from {ep.value} clashes with one already "
                                 f"registered")
            found[component.name] = component
        return found

    def reload_plugins(self) -> None:
        """Forget the loaded entry points, so that the next lookup reads the installed ones again."""
        self._plugins = None

    def builtins(self) -> list[E]:
        """The built-in entries, in the order they were added (no entry points)."""
        return list(self._builtin.values())

    def names(self) -> tuple[str, ...]:
        return tuple(self._all())

    def __contains__(self, name: object) -> bool:
        return name in self._all()

    def __iter__(self) -> Iterator[E]:
        return iter(self._all().values())

    def get(self, name: str) -> E:
        """The component `name`, or UnknownComponent naming the known ones."""
        components = self._all()
        if name not in components:
            raise UnknownComponent(f"unknown {self.family} {name!r}; known: {', '.join(components)}")
        return components[name]

    def choices_help(self) -> str:
        """`name (help); ...` for a CLI option's help text."""
        return "; ".join(f"{c.name} ({c.help})" for c in self)

    def markdown(self) -> str:
        """A docs table of the family: name, what it is, what it needs."""
        threat = any(getattr(c, "capabilities", ()) for c in self)
        lines = ["| name | what | needs |" + (" threat capabilities |" if threat else ""),
                 "|---|---|---|" + ("---|" if threat else "")]
        for c in self:
            needs = ", ".join(sorted(n.value for n in c.needs)) or "–"
            caps = f" {', '.join(sorted(c.capabilities)) or '–'} |" if threat else ""
            lines.append(f"| `{c.name}` | {c.help} | {needs} |{caps}")
        return "\n".join(lines)


def missing_needs(component: Entry, provided: frozenset[Capability]) -> list[Capability]:
    """The capabilities `component` needs that the run does not provide, in a stable order."""
    return sorted(component.needs - provided, key=lambda c: c.value)
