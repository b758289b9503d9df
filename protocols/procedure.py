"""What a run executes: a protocol file's fixed list of steps, or a script that decides its
steps as it runs. Both are *procedures*: a name, the rig kind they run on, what run.json
stores of them, and ``drive``, which hands each step to the runner in order.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from gelrig.protocols.sample import Sample
    from gelrig.protocols.spec import Step, StepSink


class Procedure(Protocol):
    """A protocol file (:class:`gelrig.protocols.spec.ProtocolSpec`) or a script
    (:class:`gelrig.protocols.script.Script`)."""

    @property
    def name(self) -> str: ...

    @property
    def rig(self) -> str: ...

    @property
    def source(self) -> str: ...

    @property
    def sample(self) -> Sample | None:
        """The run's sample (what steps take their sizes from), None when none was given."""
        ...

    @property
    def table(self) -> Mapping[str, Any]:
        """What run.json keeps under ``protocol`` (enough to run it again on resume)."""
        ...

    @property
    def steps(self) -> tuple[Step, ...]:
        """The steps known before the run starts (all of a protocol file's; none of a
        script's, which decides them as it runs): what the preflight checks up front."""
        ...

    def drive(self, sink: StepSink) -> None:
        """Send every step to ``sink`` in order."""
        ...
