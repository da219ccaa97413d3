"""Settings written once: frozen option dataclasses whose fields carry their range, and whose
descriptions are the attribute docstrings under each field (like OMPL's ParamSet).

    @dataclass(frozen=True)
    class MyOptions(Settings):
        step: float = setting(0.1, low=0.001, high=1.0)
        \"\"\"Propagation step, s.\"\"\"

    MyOptions(step=2.0)          # ValueError: step must be in [0.001, 1], got 2
    MyOptions.describe()         # (SettingSpec('step', 0.1, 'Propagation step, s.', ...),)

The node declares its parameters from `describe()` (`ros/parameters.py`), the CLI's `--set`
parses values with it, and a test checks `config/planner.yaml` against it: the default, the
range and the description live here and nowhere else.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any, cast

from rearrangement_planner.model.errors import cut_text

Value = bool | int | float | str


class SettingError(ValueError):
    """A setting's value is unusable: out of range, of the wrong type, not read by the planner
    asked for. `name` is the setting's name (or 'planner', 'seed'), so that each front end can
    say where it came from (the node's parameter, the CLI's flag, the action goal's field)
    without reading the message."""

    def __init__(self, name: str, problem: str):
        super().__init__(problem)
        self.name = name


@dataclass(frozen=True)
class SettingSpec:
    """One setting as the node and the CLI see it."""

    name: str
    default: Value
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()

    def parse(self, text: str) -> Value:
        """`text` converted to the setting's type (`--set name=text`); ValueError if it is not
        one."""
        kind = type(self.default)
        if kind is bool:
            if text.lower() in ("true", "1", "yes", "on"):
                return True
            if text.lower() in ("false", "0", "no", "off"):
                return False
            raise SettingError(self.name, f"{self.name} takes true or false, got {text!r}")
        try:
            return kind(text)
        except ValueError:
            raise SettingError(self.name,
                               f"{self.name} takes a {kind.__name__}, got {text!r}") from None


def setting(default: Value, *, low: float | None = None, high: float | None = None,
            choices: tuple[str, ...] = ()) -> Any:
    """A dataclass field with its default and its range [low, high] (or its choices)."""
    return dataclasses.field(default=default,
                             metadata={"low": low, "high": high, "choices": choices})


def internal(default: Any) -> Any:
    """A dataclass field that is not a setting: code sets it (a tolerance of the model, the
    objects a baseline treats as obstacles); `describe()` leaves it out, so no node parameter
    or `--set` reaches it."""
    return dataclasses.field(default=default, metadata={"internal": True})


@dataclass(frozen=True)
class Settings:
    """Base of the option dataclasses: checks every field against its range on construction."""

    def __post_init__(self) -> None:
        for spec in self.describe():
            check_value(spec, getattr(self, spec.name))

    @classmethod
    def describe(cls) -> tuple[SettingSpec, ...]:
        """Every field as a `SettingSpec`, in declaration order."""
        docs = _attribute_docs(cls)
        specs = []
        for f in dataclasses.fields(cls):
            if f.metadata.get("internal"):
                continue
            if not isinstance(f.default, bool | int | float | str):
                raise TypeError(f"{cls.__name__}.{f.name} needs a default made by setting()")
            specs.append(SettingSpec(f.name, f.default, docs.get(f.name, ""),
                                     f.metadata.get("low"), f.metadata.get("high"),
                                     tuple(f.metadata.get("choices", ()))))
        return tuple(specs)

    @classmethod
    def parse_assignments(cls, items: Sequence[str]) -> dict[str, Value]:
        """Values from NAME=VALUE texts (`parse_assignments` over this type's settings)."""
        return parse_assignments(cls.describe(), items)


def parse_assignments(specs: Sequence[SettingSpec], items: Sequence[str]) -> dict[str, Value]:
    """Values from NAME=VALUE texts (the command lines' --set), each parsed by its setting in
    `specs`; ValueError beginning with the offending text."""
    by_name = {spec.name: spec for spec in specs}
    values: dict[str, Value] = {}
    for item in items:
        name, sep, text = (part.strip() for part in item.partition("="))
        shown = cut_text(item, 80)
        if not sep or name not in by_name:
            raise ValueError(f"{shown}: expected NAME=VALUE with NAME one of "
                             f"{', '.join(by_name)}")
        try:
            values[name] = by_name[name].parse(text)
        except ValueError as exc:
            raise ValueError(f"{shown}: {cut_text(str(exc), 200)}") from None
    return values


def check_value(spec: SettingSpec, value: Any) -> None:
    """SettingError naming the setting if `value` is not of its type, or outside its range or
    choices."""
    kind = type(spec.default)
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise SettingError(spec.name, f"{spec.name} must be a {kind.__name__}, got {value!r}")
    if spec.choices and value not in spec.choices:
        raise SettingError(spec.name, f"{spec.name} must be one of {', '.join(spec.choices)}, "
                                      f"not {value!r}")
    if spec.low is None and spec.high is None or isinstance(value, str):
        return
    low = -math.inf if spec.low is None else spec.low
    high = math.inf if spec.high is None else spec.high
    if not low <= value <= high:     # also refuses NaN
        raise SettingError(spec.name, f"{spec.name} must be in [{low:g}, {high:g}], got {value}")


def _attribute_docs(cls: type) -> dict[str, str]:
    return _docs_of(cls)


@cache
def _docs_of(cls: Any) -> dict[str, str]:
    """The docstring under each annotated field of `cls` and its bases, folded to one line."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if klass is object or not dataclasses.is_dataclass(klass):
            continue
        body = ast.parse(textwrap.dedent(inspect.getsource(cast(type, klass)))).body[0]
        assert isinstance(body, ast.ClassDef)
        for node, after in zip(body.body, body.body[1:], strict=False):
            if (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
                    and isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant)
                    and isinstance(after.value.value, str)):
                docs[node.target.id] = " ".join(after.value.value.split())
    return docs
