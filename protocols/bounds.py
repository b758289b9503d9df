"""Bounds on the work one protocol may ask for, checked before the work starts.

Every field of a protocol is checked against its own range on load; these bound what the
fields multiply into (issue 32), so that ``gelrig plan``, ``gelrig run`` and ``gelrig
campaign`` refuse in one line, before anything is built, a protocol that no rehearsal, disk
or analysis could finish:

- ``MAX_STEPS`` steps per protocol: a rehearsal takes about 0.5 s of wall time per step
  (1000 steps: about 8 minutes);
- ``MAX_LADDER_SPEEDS`` speeds per ladder (overlaps are at most 20 by their own field);
- ``MAX_RUN_SAMPLES`` samples (rows) recorded per run: at the compression rig's 5 columns of
  8 bytes, 40 GB of HDF5, and a rehearsal counts about 2-3 million samples a second, so
  6-8 minutes (a 7-day hold at 1 kHz is 6e8 samples; at 20 kHz, 1.2e10, is refused);
- ``MAX_RUN_LAB_TIME`` of lab time per run (30 days): a rehearsal reads a hold in blocks of
  4 s of lab time at about 1 ms of wall time each, so 30 days take about 11 minutes.

A step kind says what it records in its plan (:attr:`StepPlan.samples`); one that does not
(0) is bounded by lab time only.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:  # step kinds import the bounds
    from gelrig.protocols.steps.base import StepPlan

MAX_STEPS = 1000
MAX_LADDER_SPEEDS = 100
MAX_RUN_SAMPLES = 1_000_000_000
MAX_RUN_LAB_TIME = 30 * 86400.0


@dataclass(frozen=True)
class Beyond:
    """A run beyond a bound: the quantity, its value and what is allowed (and why)."""

    field: str
    value: str
    allowed: str

    def line(self) -> str:
        return f"{self.field} {self.value}: {self.allowed}"

    def error(self, source: str | None) -> ConfigError:
        return ConfigError(self.field, self.value, self.allowed, source)


def run_bound_error(plans: Iterable[tuple[str, StepPlan]]) -> Beyond | None:
    """Why a run of these planned steps (``(label, plan)``, label ``step 1 (ramp and hold)``)
    is beyond the bounds, naming its largest step; None within them."""
    samples = lab = 0.0
    worst_samples: tuple[float, str] = (0.0, "")
    worst_lab: tuple[float, str] = (0.0, "")
    for label, plan in plans:
        samples += plan.samples
        lab += plan.duration
        worst_samples = max(worst_samples, (plan.samples, label))
        worst_lab = max(worst_lab, (plan.duration, label))
    if samples > MAX_RUN_SAMPLES:
        return Beyond("samples per run", f"{samples:,.0f}",
                      f"at most {MAX_RUN_SAMPLES:,} ({worst_samples[1]} records "
                      f"{worst_samples[0]:,.0f}); shorten a hold, lower a rate or split the "
                      "protocol")
    if lab > MAX_RUN_LAB_TIME:
        return Beyond("lab time per run", _days(lab),
                      f"at most {_days(MAX_RUN_LAB_TIME)} ({worst_lab[1]} lasts "
                      f"{_days(worst_lab[0])}); shorten it or split the protocol")
    return None


def _days(seconds: float) -> str:
    return f"{seconds / 86400:,.1f} days"
