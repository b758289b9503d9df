"""Who answers bring-up's questions: a person at the console, or the twin playing one.

Bring-up needs the things only a person at the rig knows: whether the plate went down, what
the dial gauge reads, which mass sits on the load cell, what the conditioner's gain is set to,
and a yes before every motion and every value written. :class:`Operator` is that contract.
:class:`ConsoleOperator` asks on a terminal; :class:`TwinOperator` answers from a simulated
rig's hidden truth with a real operator's reading errors (a dial gauge read to +-2 um,
masses known to 0.1 %), so bring-up is rehearsed and tested end to end.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.units import to_si

if TYPE_CHECKING:  # the simulators are imported by whoever builds the twin
    from gelrig.simulators.twins.compression import CompressionTwin

#: Standard gravity (m/s^2): a mass's weight. The local value differs by up to ~0.3 %;
#: bring-up records that it used this one.
GRAVITY = 9.80665
#: A dial gauge's reading error (m): the twin's readings are off by up to this, uniformly.
GAUGE_ERROR = 2e-6
#: A calibration mass's tolerance (relative): the twin's true masses differ by up to this.
MASS_TOLERANCE = 1e-3

TOWARD, AWAY = "toward", "away"


@runtime_checkable
class Operator(Protocol):
    """The person (or twin) at the rig. ``key`` names a question so a script can answer it
    (``stage.scale``, ``write [stage] counts_per_mm``)."""

    name: str

    def say(self, text: str) -> None:
        """Tell the operator what happens next, or what was found."""
        ...

    def confirm(self, key: str, question: str) -> bool:
        """A yes/no question; only a yes lets a motion start or a value be written."""
        ...

    def zero_gauge(self) -> None:
        """Zero the dial gauge resting on the plate where it is now."""
        ...

    def gauge_reading(self) -> float:
        """The dial gauge's reading now (m, positive when the plate moved towards the
        sample)."""
        ...

    def plate_went(self) -> str:
        """Which way the plate just went: :data:`TOWARD` the sample or :data:`AWAY`."""
        ...

    def load_mass(self, nominal: float) -> float:
        """Put a calibration mass of about ``nominal`` kg on the load cell; its marked mass
        (kg)."""
        ...

    def unload(self) -> None:
        """Take every mass (and the sample) off the load cell."""
        ...

    def conditioner_gain(self, believed: float) -> float:
        """The conditioner's gain as set on the device (V/V); ``believed`` is the rig file's."""
        ...


class ConsoleOperator:
    """A person at the terminal: prompts on ``write``, answers from ``read`` (``input``)."""

    def __init__(self, name: str = "operator", read: Callable[[str], str] | None = None,
                 write: Callable[[str], None] | None = None):
        self.name = name
        # looked up when called: the terminal's input and print of the moment
        self._read = read or (lambda prompt: input(prompt))
        self._write = write or (lambda text: print(text, flush=True))

    def say(self, text: str) -> None:
        self._write(text)

    def confirm(self, key: str, question: str) -> bool:
        while True:
            answer = self._read(f"{question} [y/n] ").strip().lower()
            if answer in ("y", "yes"):
                return True
            if answer in ("n", "no"):
                return False
            self._write("  answer y or n")

    def _quantity(self, prompt: str, unit: str, display: str, scale: float) -> float:
        """A number in ``display`` units (a bare number) or any quantity of ``unit``."""
        while True:
            text = self._read(f"{prompt} ({display}): ").strip()
            try:
                return float(text) * scale
            except ValueError:
                pass
            try:
                return to_si(text, unit, prompt)
            except ConfigError as exc:
                self._write(f"  {exc}")

    def zero_gauge(self) -> None:
        self._read("Set the dial gauge on the plate and zero it; press Enter when done ")

    def gauge_reading(self) -> float:
        return self._quantity("Dial gauge reading", "m", "mm", 1e-3)

    def plate_went(self) -> str:
        while True:
            answer = self._read("Did the plate move towards the sample or away? "
                                "[toward/away] ").strip().lower()
            if answer in (TOWARD, "t", "towards"):
                return TOWARD
            if answer in (AWAY, "a"):
                return AWAY
            self._write("  answer toward or away")

    def load_mass(self, nominal: float) -> float:
        return self._quantity(f"Put about {nominal * 1e3:g} g on the load cell; its marked "
                              "mass", "kg", "g", 1e-3)

    def unload(self) -> None:
        self._read("Take every mass and the sample off the load cell; press Enter when done ")

    def conditioner_gain(self, believed: float) -> float:
        text = self._read(f"The conditioner's gain as set on the device (Enter: {believed:g}) "
                          ": ").strip()
        return believed if not text else self._parse_gain(text, believed)

    def _parse_gain(self, text: str, believed: float) -> float:
        try:
            gain = float(text)
        except ValueError:
            gain = -1.0
        if gain > 0:
            return gain
        self._write(f"  gain {text!r}: a positive number; kept {believed:g}")
        return believed


@dataclass
class TwinOperator:
    """The twin playing the operator: answers from the simulated rig's truth.

    ``twin`` is the rig's :class:`~gelrig.simulators.twins.compression.CompressionTwin`.
    The dial gauge reads the plate's true travel since it was zeroed, off by up to
    :data:`GAUGE_ERROR`; a mass put on the cell weighs its marked value times (1 +- up to
    :data:`MASS_TOLERANCE`); the gain read off the conditioner is the simulated one. Every
    question is answered yes but those whose key is in ``declines``.
    """

    twin: CompressionTwin
    clock: Clock
    seed: int = 0
    declines: Iterable[str] = ()
    name: str = "twin"
    #: what the twin was told, in order (a test reads it)
    said: list[str] | None = None

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        self._zero = 0.0
        self._declines = tuple(self.declines)
        if self.said is None:
            self.said = []

    def _plate(self) -> float:
        return float(self.twin.plate(np.array([self.clock.now()]))[0])

    def say(self, text: str) -> None:
        assert self.said is not None
        self.said.append(text)

    def confirm(self, key: str, question: str) -> bool:
        yes = not any(key == d or key.startswith(f"{d} ") or key.startswith(f"{d}.")
                      for d in self._declines)
        self.say(f"{question} -> {'yes' if yes else 'no'}")
        return yes

    def zero_gauge(self) -> None:
        self._zero = self._plate()

    def gauge_reading(self) -> float:
        return self._plate() - self._zero + float(self._rng.uniform(-GAUGE_ERROR, GAUGE_ERROR))

    def plate_went(self) -> str:
        # a larger position always carries the twin's plate towards the sphere; the question
        # follows a move to a larger position, so the answer is the sign of the plate's travel
        moved = self._plate() - self._zero
        return TOWARD if moved > 0 else AWAY

    def load_mass(self, nominal: float) -> float:
        true = nominal * (1.0 + float(self._rng.uniform(-MASS_TOLERANCE, MASS_TOLERANCE)))
        self.twin.signal.dead_load = true * GRAVITY
        return nominal

    def unload(self) -> None:
        self.twin.signal.dead_load = 0.0

    def conditioner_gain(self, believed: float) -> float:
        return float(self.twin.signal.chain.gain)


__all__ = ["AWAY", "GAUGE_ERROR", "GRAVITY", "MASS_TOLERANCE", "TOWARD", "ConsoleOperator",
           "Operator", "TwinOperator"]
