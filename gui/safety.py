"""One source of truth for the rig's safety state (issue 25): the banner, the header, the
Instruments tab and the status bar all render one :class:`Safety` snapshot made by
:class:`~gelrig.gui.desk.RigDesk`, so they cannot disagree.

A value is "now" only while its instrument answers; from an instrument that stopped
answering it is shown with its age and greyed. The state a person reads first:
``off`` (no rig), ``silent`` (an instrument does not answer: nothing is monitored),
``tripped`` (a trip or fault not acknowledged) or ``armed``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from gelrig.gui.fmt import quantity
from gelrig.protocols.rig import CompressionLimits, ShearLimits

#: Instrument key of the rig -> the name on its label (and at the head of its drivers' errors).
NAMES: dict[str, str] = {"stage": "KDC101", "force": "USB-6001", "rheometer": "MCR 501"}
#: Driver message prefix -> instrument key.
KEYS: dict[str, str] = {name: key for key, name in NAMES.items()}
#: Reading column -> the instrument that answers it.
SOURCE: dict[str, str] = {
    "position_m": "stage", "moving": "stage", "homed": "stage", "force_N": "force",
    "gap_m": "rheometer", "angle_rad": "rheometer", "theta_m": "rheometer",
    "torque_Nm": "rheometer", "normal_force_N": "rheometer", "gap_referenced": "rheometer"}
#: An instrument unheard for longer than this (s, wall time) is silent while idle: the idle
#: readout asks every 0.2 s.
SILENT_AFTER = 1.0
#: The same during a run, from its sample blocks (a block is at most 0.5 s of lab time).
RUN_SILENT_AFTER = 1.5
#: A value older than this (s) is shown with its age, greyed.
STALE_AFTER = 1.0

GREY = "color:#8a8a8a;"


def ago(seconds: float) -> str:
    """'3 s ago', '2.5 min ago' (lab words: s / min / h)."""
    if seconds < 60:
        return f"{seconds:.0f} s ago"
    if seconds < 3600:
        return f"{seconds / 60:.1f} min ago"
    return f"{seconds / 3600:.1f} h ago"


def lasted(seconds: float) -> str:
    """'3 s', '2.5 min', '1.2 h'."""
    return ago(seconds).removesuffix(" ago")


@dataclass(frozen=True)
class Silent:
    """An instrument that does not answer: its name, for how long (s), and the last error
    in words ("" when it simply gave no answer)."""

    name: str
    seconds: float
    error: str = ""

    def text(self) -> str:
        why = f" ({self.error})" if self.error else ""
        return f"{self.name} silent for {lasted(self.seconds)}{why}"


@dataclass(frozen=True)
class Safety:
    """What is known about the rig's safety now; every view renders only this."""

    connected: bool = False
    why_off: str = "no rig connected"
    running: bool = False
    wedged: bool = False
    alarm: str = ""  # the unacknowledged trip or fault ("" when none)
    silent: tuple[Silent, ...] = ()
    busy: str = ""  # a command the rig thread is in for longer than SILENT_AFTER
    safe_line: str = ""  # the latest verified-stop line (stop, trip, fault, unload)
    safe_verified: bool | None = None
    pending: str = ""  # a safe stop not confirmed, being retried: what is said about it
    loaded: str = ""  # why the sample counts as loaded ("" when not, or not known)
    overlap_armed: bool | None = None  # None: the rig has no first-touch overlap limit
    limits: str = "no rig"
    values: Mapping[str, float] = field(default_factory=dict)
    ages: Mapping[str, float] = field(default_factory=dict)  # column -> s since read

    @property
    def state(self) -> str:
        """``off`` / ``silent`` / ``tripped`` / ``armed``."""
        if not self.connected:
            return "off"
        if self.silent or self.wedged or self.busy:
            return "silent"
        return "tripped" if self.alarm else "armed"

    def why_not_monitoring(self) -> str:
        """'MCR 501 silent for 3 s (...)' for the silent state, else ''."""
        if self.wedged:
            return "the rig thread is stuck in an instrument call"
        if self.silent:
            return "; ".join(s.text() for s in self.silent)
        return f"busy: {self.busy}" if self.busy else ""

    def fresh(self, key: str) -> bool:
        return key in self.values and self.ages.get(key, 0.0) <= STALE_AFTER

    def value_text(self, key: str, label: str, unit: str) -> str:
        """'force 4.1 mN' when fresh, 'force 4.1 mN (5 s ago)' when stale."""
        shown = f"{self.values[key] * 1e3:.4g} mm" if unit == "m" else quantity(
            self.values[key], unit)
        if self.fresh(key):
            return f"{label} {shown}"
        return f"{label} {shown} ({ago(self.ages.get(key, 0.0))})"

    def live(self, keys: tuple[tuple[str, str, str], ...]) -> tuple[str, str]:
        """(fresh values, stale values with their ages) among ``keys`` (column, label, unit)."""
        fresh = [self.value_text(k, label, unit) for k, label, unit in keys
                 if k in self.values and self.fresh(k)]
        stale = [self.value_text(k, label, unit) for k, label, unit in keys
                 if k in self.values and not self.fresh(k)]
        return ", ".join(fresh), ", ".join(stale)

    def status_line(self) -> str:
        """The status bar's one line."""
        state = self.state
        if state == "off":
            return f"not monitoring: {self.why_off}"
        if state == "silent":
            text = f"NOT MONITORING: {self.why_not_monitoring()}"
        elif state == "tripped":
            text = f"TRIPPED: {self.alarm}"
        else:
            text = "interlocks armed"
            if self.overlap_armed is False:
                text += "; overlap limit NOT ARMED (no contact search yet)"
        if self.safe_line and state != "armed":
            text += f"; last stop: {self.safe_line}"
        if self.pending:
            text += f"; {self.pending}"
        if self.loaded:
            text += f"; sample loaded ({self.loaded})"
        return text


def limits_text(limits: CompressionLimits | ShearLimits | None) -> str:
    """'force ≤ 2 N, overlap ≤ 2.5 mm' (lengths in mm)."""
    if limits is None:
        return "no rig"
    return ", ".join(f"{what} ≤ {value * 1e3:g} mm" if unit == "m" else
                     f"{what} ≤ {quantity(value, unit)}" for what, value, unit in limits.guards())


def source_of(message: str) -> str | None:
    """The instrument key a driver's error message names at its head, if any."""
    return next((key for name, key in KEYS.items() if message.startswith(name)), None)
