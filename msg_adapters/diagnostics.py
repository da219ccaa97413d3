"""The planner status (docs/design.md) as a diagnostic_msgs/DiagnosticArray, on `/diagnostics`.

One DiagnosticStatus: level OK while idle, planning or after a success, WARN after a cancel
or a fragile success, ERROR after a failure; message "<state>: <message>"; one KeyValue per
`PlannerStatus` field, numbers written with `repr` so that they read back exactly (inf as
'inf'), booleans as 'True' / 'False'.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header

from rearrangement_planner.model.errors import InputError
from rearrangement_planner.planning.requests.status import PlannerStatus

LEVELS = {
    "idle": DiagnosticStatus.OK,
    "planning": DiagnosticStatus.OK,
    "succeeded": DiagnosticStatus.OK,
    "cancelled": DiagnosticStatus.WARN,
    "failed": DiagnosticStatus.ERROR,
}
"""The diagnostic level of each planner state."""

_FIELDS = {f.name: f for f in dataclasses.fields(PlannerStatus)}


def _boolean(text: str) -> bool:
    if text not in ("True", "False"):
        raise ValueError(text)
    return text == "True"


_PARSERS: dict[str, Callable[[str], object]] = {
    "iterations": int, "tree_size": int, "best_goal_distance": float, "elapsed": float,
    "fragile": _boolean}


def status_to_diagnostics(status: PlannerStatus, stamp: Time | None = None,
                          name: str = "rearrangement_planner") -> DiagnosticArray:
    """A DiagnosticArray with one DiagnosticStatus called `name` describing `status`."""
    message = f"{status.state}: {status.message}" if status.message else status.state
    values = [KeyValue(key=key, value=repr(value) if not isinstance(value, str) else value)
              for key, value in dataclasses.asdict(status).items()]
    return DiagnosticArray(
        header=Header(stamp=stamp if stamp is not None else Time()),
        status=[DiagnosticStatus(level=DiagnosticStatus.WARN if status.fragile
                                 else LEVELS[status.state], name=name, message=message,
                                 hardware_id="", values=values)])


def diagnostics_to_status(msg: DiagnosticArray, name: str | None = None) -> PlannerStatus:
    """The PlannerStatus in `msg`: the first DiagnosticStatus with a 'state' value (or, when
    `name` is given, the one called `name`). Missing values take their defaults."""
    for i, diagnostic in enumerate(msg.status):
        values = {kv.key: kv.value for kv in diagnostic.values}
        if (name is None and "state" in values) or (name is not None and diagnostic.name == name):
            return _parse(values, f"status.status[{i}]")
    wanted = f"called '{name}'" if name is not None else "with a 'state' value"
    raise InputError("status.status",
                     f"has no DiagnosticStatus {wanted} (got "
                     f"{', '.join(repr(d.name) for d in msg.status) or 'none'}); "
                     f"publish one with status_to_diagnostics")


def _parse(values: dict[str, str], field: str) -> PlannerStatus:
    kwargs: dict[str, object] = {}
    for key, text in values.items():
        if key not in _FIELDS:
            continue  # extra diagnostic values are allowed
        parse = _PARSERS.get(key, str)
        try:
            kwargs[key] = parse(text)
        except ValueError:
            need = {int: "an integer", _boolean: "True or False"}.get(parse, "a number")
            raise InputError(f"{field}.values[{key}]", f"is {text!r}; need {need}") from None
    if "state" not in kwargs:
        raise InputError(f"{field}.values", "has no 'state' value; every status needs one")
    try:
        return PlannerStatus(**kwargs)  # type: ignore[arg-type]
    except ValueError as e:
        raise InputError(f"{field}.values", str(e)) from None
