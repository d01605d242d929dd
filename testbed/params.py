"""Component parameters, typed and validated one way: each family's parameters are a pydantic model
(`Params`), built from a TOML table or `--set` values, and a bad value is a one-line `ParamsError` naming
the table and key. The models also give the scenario's JSON Schema and its key reference.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model
from pydantic_core import ErrorDetails

from testbed.errors import UserError


class ParamsError(UserError):
    """Parameters that do not validate; the message is one line naming the table and the key."""


class Params(BaseModel):
    """Frozen, strict (no strings for numbers, no booleans for numbers; ints are accepted for floats),
    finite, and no unknown keys."""

    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)

    def explicit(self) -> dict[str, Any]:
        """The table as TOML would hold it, defaults left out."""
        return self.model_dump(exclude_defaults=True)


P = TypeVar("P", bound=BaseModel)


_PLAIN = {"float_type": "must be a number", "int_type": "must be an integer", "finite_number": "must be finite",
          "string_type": "must be a string", "bool_type": "must be true or false", "dict_type": "must be a table",
          "model_type": "must be a table", "list_type": "must be a list"}
_BOUNDS = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}


def error_key(err: ErrorDetails) -> str:
    """The dotted key of one pydantic error (a bad table key is named by itself)."""
    return ".".join(str(p) for p in err["loc"] if p != "[key]")


def error_problem(err: ErrorDetails) -> str:
    """What is wrong, in the words every one-line refusal uses: 'missing', 'unknown key', 'must be > 0, got -1'."""
    kind, got = err["type"], f", got {err.get('input')!r}"
    if kind == "missing":
        return "missing"
    if kind == "extra_forbidden":
        return "unknown key"
    if kind in _BOUNDS:
        return f"must be {_BOUNDS[kind]} {next(iter(err['ctx'].values()))}{got}"
    if kind == "literal_error":
        return f"must be one of {err['ctx']['expected']}{got}"
    if kind == "value_error":
        return err["msg"].removeprefix("Value error, ")
    if kind in _PLAIN:
        return _PLAIN[kind] + got
    return err["msg"].lower().removeprefix("input should be ").join(("should be ", "")) + got


def validate_params(model: type[P], table: Mapping[str, Any], where: str) -> P:
    """`model` built from `table`, or ParamsError: `[where] 'key' ...: what is wrong` (unknown keys name
    the known ones)."""
    try:
        return model.model_validate(dict(table))
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(p) for p in err["loc"])
        if err["type"] == "extra_forbidden":
            known = ", ".join(model.model_fields) or "none"
            raise ParamsError(f"[{where}] unknown parameter {key!r}; known: {known}") from None
        if err["type"] == "missing":
            raise ParamsError(f"[{where}] missing required parameter {key!r}") from None
        if not key:
            raise ParamsError(f"[{where}] {error_problem(err)}") from None
        raise ParamsError(f"[{where}] {key!r} {error_problem(err)}") from None


def params_from_signature(name: str, function: Callable[..., Any], skip: tuple[str, ...] = (),
                          descriptions: Mapping[str, str] | None = None) -> type[Params]:
    """A `Params` model of `function`'s keyword parameters (their annotations and defaults; no default means
    required), without those in `skip`: one source for a component's defaults, its validation and its docs."""
    hints = typing.get_type_hints(function)
    fields: dict[str, Any] = {}
    for pname, p in inspect.signature(function).parameters.items():
        if pname in skip or pname == "self" or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            continue
        default = ... if p.default is inspect.Parameter.empty else p.default
        description = (descriptions or {}).get(pname)
        fields[pname] = (hints.get(pname, Any), Field(default, description=description))
    return create_model(name, __base__=Params, **fields)


def reference_rows(model: type[BaseModel]) -> list[tuple[str, str, str, str]]:
    """(key, type, default, description) of every field, for the docs' key reference."""
    rows = []
    for key, field in model.model_fields.items():
        typ = _type_name(field.annotation)
        default = ("required" if field.is_required() else repr(field.default_factory()) if field.default_factory
                   else repr(field.default))
        rows.append((key, typ, default, field.description or ""))
    return rows


def _type_name(annotation: Any) -> str:
    if isinstance(annotation, type):
        return annotation.__name__
    return str(annotation).replace("typing.", "")
