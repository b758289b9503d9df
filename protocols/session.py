"""A recorded run: one protocol on a built rig, every event into its run directory.

The one wiring of a recorded run, shared by ``gelrig run`` / ``resume`` / ``demo`` and the GUI:
the Recorder as a critical subscriber (a run that cannot record stops), the instruments'
identities and the status in run.json, and the Runner. Building the rig stays with the caller
(the composition root's factory); so do the faces of the run (console, live plots), which are
further subscribers of the same bus.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from instrument.errors import GelrigError
from instrument.store import RunDirectory
from protocols.control import RunControl
from protocols.events import EventBus, RunState
from protocols.procedure import Procedure
from protocols.recorder import Recorder
from protocols.rig import Rig
from protocols.runner import Runner


class RecordedRun:
    """Runs ``protocol`` on ``rig`` once it records into a run directory.

    Made in two steps so that nothing is written for a protocol the rig cannot run: the
    constructor checks that (GelrigError), :meth:`record` wires the run directory, :meth:`run`
    runs the steps on the calling thread (the GUI calls it on its rig thread). ``completed``
    holds the results of the steps a resumed run skips.
    """

    def __init__(
        self,
        rig: Rig,
        protocol: Procedure,
        bus: EventBus | None = None,
        control: RunControl | None = None,
        completed: Mapping[int, Mapping[str, Any]] | None = None,
    ):
        self.rig = rig
        self.bus = EventBus() if bus is None else bus
        self.control = RunControl() if control is None else control
        self.runner = Runner(rig, protocol, self.bus, self.control, completed)
        self.directory: RunDirectory | None = None

    def record(self, run: RunDirectory) -> RecordedRun:
        """Record into ``run`` from now on: the Recorder subscribes as critical, and run.json
        gets the instruments' identities and status "running". Returns self."""
        if self.directory is not None:
            raise GelrigError(f"this run already records into {self.directory.path}")
        self.bus.subscribe(Recorder(run), critical=True)
        run.update(instruments=self.rig.identities, status="running")
        # what a resumed script must ask for again at each completed step
        self.runner.recorded = {i: (str(s.get("name")), str(s.get("kind")))
                                for i, s in run.completed_steps().items()}
        self.directory = run
        return self

    def run(self) -> RunState:
        """Run every step not yet completed; returns the final state. Needs :meth:`record`."""
        if self.directory is None:
            raise GelrigError("a run records into a run directory: call record(run) first")
        return self.runner.run()

    @property
    def state(self) -> RunState:
        return self.runner.state

    @property
    def reason(self) -> str:
        """Why the run ended ('all steps completed', the abort or fault message)."""
        return self.runner.reason
