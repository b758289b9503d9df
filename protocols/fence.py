"""Safe stop first: the rig's safe stop runs the moment a step's instrument call fails.

While a step runs, the runner arms the rig's :class:`Fence`. Every instrument call of the
rig passes through it (the caps' views and :class:`FencedForce` route their calls here).
The first call that fails with an instrument error runs the rig's safe stop at once, before
the error propagates: before the step's own cleanup (``finally`` blocks that stop a stream
or a rotation), which would otherwise talk to a frozen instrument first and spend a reply
timeout on each call. From then on the step's calls are refused at once
(:class:`FenceClosed`), and a stop is a no-op (the safe stop has sent it); the runner takes
the safe state and the first error (:attr:`Fence.cause`) for its record.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from gelrig.instrument.contracts.loadcell import ForceBlock, ForceOverRangeError, ForceSensor
from gelrig.instrument.core.errors import InstrumentError
from gelrig.instrument.core.identity import Identity
from gelrig.protocols.safestop import SafeState

T = TypeVar("T")

#: What the fence calls on the first fault: the instrument's name and the error; returns
#: what the safe stop verified.
OnFault = Callable[[str, BaseException], SafeState]


class FenceClosed(InstrumentError):
    """A step's instrument call after a fault: refused, the rig's safe stop ran first."""


class Fence:
    """The rig's gate between a step and its instruments while a run is on its way out."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._on_fault: OnFault | None = None
        self._bypass = 0
        #: the first instrument error of the armed span, and which instrument raised it
        self.cause: BaseException | None = None
        self.instrument = ""
        #: what the safe stop verified, once one ran in the armed span (the fence's own, or
        #: one run from outside the run's thread)
        self.safe_state: SafeState | None = None
        #: the instrument a step's call is in now ('' between calls): a safe stop from
        #: outside the run's thread leaves it alone (it is stuck there)
        self.busy = ""

    @property
    def armed(self) -> bool:
        return self._on_fault is not None

    @contextlib.contextmanager
    def arm(self, on_fault: OnFault) -> Iterator[Fence]:
        """Within the block, the first instrument error runs ``on_fault`` before it
        propagates; the cause and safe state are kept after it for the runner."""
        with self._lock:
            self._on_fault, self.cause, self.instrument, self.safe_state = on_fault, None, "", None
        try:
            yield self
        finally:
            with self._lock:
                self._on_fault = None

    @contextlib.contextmanager
    def open(self) -> Iterator[None]:
        """The safe stop's own calls pass (from any thread) while it runs."""
        with self._lock:
            self._bypass += 1
        try:
            yield
        finally:
            with self._lock:
                self._bypass -= 1

    def record(self, safe: SafeState) -> None:
        """A safe stop ran while armed (from inside or outside the run's thread)."""
        with self._lock:
            if self.armed and self.safe_state is None:
                self.safe_state = safe

    def call(self, instrument: str, what: str, fn: Callable[[], T]) -> T:
        """``fn()``, an instrument call of ``instrument``; see the module."""
        if self._bypass or self._on_fault is None:
            return fn()
        if self.cause is not None or self.safe_state is not None:
            return self._refuse(instrument, what)
        self.busy = instrument
        try:
            return fn()
        except ForceOverRangeError:
            raise  # a reading beyond the input's range: the recorder keeps it, then stops
        except InstrumentError as exc:
            self.busy = ""
            self._fault(instrument, exc)
            raise
        finally:
            self.busy = ""

    def _refuse(self, instrument: str, what: str) -> Any:
        if what == "stop":
            return None  # the safe stop has sent it (or is sending it)
        raise FenceClosed(f"{instrument} {what} skipped: the rig's safe stop ran after "
                          f"{type(self.cause).__name__ if self.cause else 'a fault'}")

    def _fault(self, instrument: str, exc: BaseException) -> None:
        with self._lock:
            on_fault = self._on_fault
            if on_fault is None or self.cause is not None:
                return
            self.cause, self.instrument = exc, instrument
            done = self.safe_state is not None
        if not done:
            safe = on_fault(instrument, exc)
            with self._lock:
                if self.safe_state is None:
                    self.safe_state = safe


class FencedForce:
    """The rig's force sensor with its calls through the rig's :class:`Fence`."""

    def __init__(self, force: ForceSensor, fence: Fence):
        self.inner = force
        self.fence = fence

    def __getattr__(self, name: str) -> Any:  # driver extras (chain, config, ...) pass on
        return getattr(self.inner, name)

    @property
    def rate(self) -> float:
        return self.inner.rate

    def identify(self) -> Identity:
        return self.fence.call("force", "identify", self.inner.identify)

    def start(self, rate_hz: float) -> None:
        self.fence.call("force", "start", lambda: self.inner.start(rate_hz))

    def read_block(self, n: int | None = None, timeout: float | None = None) -> ForceBlock:
        return self.fence.call("force", "read", lambda: self.inner.read_block(n, timeout))

    def tare(self, duration: float = 1.0) -> float:
        return self.fence.call("force", "tare", lambda: self.inner.tare(duration))

    def zero_on(self, volts: Any) -> float:
        return self.inner.zero_on(volts)  # arithmetic on samples read: no instrument call

    def stop(self) -> None:
        self.fence.call("force", "stop acquisition", self.inner.stop)

    def close(self) -> None:
        self.inner.close()
