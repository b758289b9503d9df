"""What every bring-up routine shares: the session (rig, operator, Stop), guarded motions,
and the values a routine proposes for the confirmed rig file."""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass, field

from gelrig.bringup.confirmed_file import Confirmed
from gelrig.bringup.operator import Operator
from gelrig.instrument.core.errors import GelrigError
from gelrig.protocols.control import RunControl
from gelrig.protocols.manual_motion import guarded
from gelrig.protocols.rig import Rig
from gelrig.protocols.rigfile import RigSpec


class BringupStopped(GelrigError):
    """A guarded motion ended on a Stop or an interlock trip: the routine ends there (what the
    safe stop verified is in the message)."""


@dataclass
class Session:
    """One bring-up: the rig, who answers, the Stop every motion obeys, and the values
    proposed so far (each written only after the operator's yes)."""

    rig: Rig
    operator: Operator
    #: the rig file as read (what the rig believes about its instruments)
    spec: RigSpec | None = None
    control: RunControl = field(default_factory=RunControl)
    proposed: list[Confirmed] = field(default_factory=list)
    #: what each routine found, one line each (the report printed at the end)
    findings: list[str] = field(default_factory=list)
    date: str = field(default_factory=lambda: dt.datetime.now(dt.UTC).strftime(
        "%Y-%m-%dT%H:%MZ"))

    def found(self, line: str) -> None:
        self.findings.append(line)
        self.operator.say(f"  found: {line}")

    def propose(self, table: str, key: str, value: float | str, method: str,
                uncertainty: str) -> None:
        self.proposed.append(Confirmed(table, key, value, method, uncertainty,
                                       self.operator.name, self.date))

    def ask(self, key: str, plan: str) -> bool:
        """Say what a step will do and ask before it (nothing happens on a no)."""
        self.operator.say(plan)
        yes = self.operator.confirm(key, f"Go ahead with {key}?")
        if not yes:
            self.operator.say(f"  {key} skipped: nothing moved, nothing will be written")
        return yes

    def move(self, what: str, start: Callable[[], object], toward: bool,
             on_values: Callable[[dict[str, float]], None] | None = None) -> None:
        """Run a motion under the rig's interlocks and Stop (manual_motion.guarded); a trip or
        Stop ends the routine with the verified stop's line."""
        result = guarded(self.rig, what, start, self.control, on_values, toward)
        if result.outcome != "done":
            verified = result.safe.line() if result.safe is not None else "stop not verified"
            raise BringupStopped(f"{what} {result.outcome}: {result.reason}; {verified}")


def percent(u: float, value: float) -> str:
    return f"{abs(u / value) * 100:.3g} %"


__all__ = ["BringupStopped", "Session", "percent"]
