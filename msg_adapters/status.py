"""The planner status (docs/design.md, the `~/status` topic) as our own typed message,
rearrangement_interfaces/msg/PlannerStatus: one field per `PlannerStatus` field, and a header
with the stamp. The same status goes to `/diagnostics` as a DiagnosticArray (`diagnostics.py`)
for the ROS diagnostics tools."""

from __future__ import annotations

import dataclasses

from builtin_interfaces.msg import Time
from std_msgs.msg import Header

from rearrangement_interfaces.msg import PlannerStatus as PlannerStatusMsg
from rearrangement_planner.model.errors import InputError
from rearrangement_planner.planning.requests.status import PlannerStatus


def status_to_msg(status: PlannerStatus, stamp: Time | None = None) -> PlannerStatusMsg:
    """The typed ~/status message of `status`."""
    return PlannerStatusMsg(header=Header(stamp=stamp if stamp is not None else Time()),
                            **dataclasses.asdict(status))


def msg_to_status(msg: PlannerStatusMsg) -> PlannerStatus:
    """The PlannerStatus of a ~/status message; InputError names a field out of range."""
    values = {f.name: getattr(msg, f.name) for f in dataclasses.fields(PlannerStatus)}
    try:
        return PlannerStatus(**values)
    except ValueError as exc:
        raise InputError("status", str(exc)) from None
