"""One bring-up from start to end: connect, run each instrument's routines, write what the
operator accepts.

Every routine says what it will do and asks first; every motion runs under the rig's
interlocks and Stop. At the end each proposed value is put to the operator one by one, and
only accepted values reach the confirmed rig file (none accepted: no file). A Stop, a trip or
Ctrl-C ends the routines with the stop delivered and read back.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gelrig.bringup import confirmed_file
from gelrig.bringup.common import BringupStopped, Session
from gelrig.bringup.operator import Operator, TwinOperator
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import ConfigError, GelrigError
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig
from gelrig.protocols.rigfile import RigSpec, load_rig


@dataclass(frozen=True)
class Outcome:
    """What a bring-up found and wrote (``written`` None: nothing was)."""

    findings: list[str]
    written: Path | None
    accepted: list[confirmed_file.Confirmed]
    declined: list[confirmed_file.Confirmed]


def default_out(rig_file: Path) -> Path:
    """``rig.toml`` -> ``rig.confirmed.toml`` beside it."""
    return rig_file.with_name(f"{rig_file.stem}.confirmed.toml")


def connect(spec: RigSpec) -> tuple[Rig, Clock]:
    """The rig's instruments on the time base they need: virtual for a simulated rig."""
    from gelrig.factory import build_rig
    from gelrig.instrument.core.clock import RealClock, VirtualClock

    clock: Clock = VirtualClock() if spec.simulated else RealClock()
    return build_rig(spec, clock, in_process=spec.simulated), clock


def check_twin(spec: RigSpec) -> None:
    """The twin can play the operator only on a fully simulated rig."""
    if not spec.simulated:
        raise ConfigError("--operator", "twin", "needs a fully simulated rig (every "
                          "transport = \"simulator\")", spec.source)


def twin_operator(rig: Rig, clock: Clock, source: str, seed: int = 0,
                  declines: tuple[str, ...] = ()) -> TwinOperator:
    """The twin as the operator of a simulated rig."""
    if rig.twin is None:
        raise ConfigError("--operator", "twin", "needs a fully simulated rig (every "
                          "transport = \"simulator\")", source)
    return TwinOperator(rig.twin, clock, seed=seed, declines=declines)  # type: ignore[arg-type]


def routines(session: Session) -> list[Callable[[], None]]:
    """The instruments' routines for the session's rig, in order."""
    if isinstance(session.rig, CompressionRig):
        from gelrig.bringup.loadcell import LoadCellBringup
        from gelrig.bringup.stage import StageBringup

        return [StageBringup(session).run, LoadCellBringup(session).run]
    assert isinstance(session.rig, ShearRig)
    from gelrig.bringup.rheometer import RheometerBringup

    return [RheometerBringup(session).run]


def run(rig_file: Path, operator: Operator | Callable[[Rig, Clock, str], Operator],
        out: Path | None = None) -> Outcome:
    """Bring up the rig of ``rig_file``; ``operator`` is one, or makes one for the connected
    rig (the twin operator needs the rig's twin)."""
    spec = load_rig(rig_file)
    out = out or default_out(rig_file)
    rig, clock = connect(spec)
    try:
        who = operator if isinstance(operator, Operator) else operator(rig, clock, spec.source)
        session = Session(rig, who, spec)
        who.say(f"Bring-up of {spec.name} ({spec.source}); confirmed values go to {out}, "
                "each only after your yes.")
        for routine in routines(session):
            try:
                routine()
            except BringupStopped as exc:
                who.say(f"STOPPED: {exc}")
                break
            except GelrigError as exc:
                who.say(f"{type(exc).__name__}: {exc}")
        rig.stop_all()
        return _write(session, rig_file, out)
    except KeyboardInterrupt:
        from gelrig.protocols.manual_motion import verified_stop

        print(f"interrupted: {verified_stop(rig, 'Ctrl-C at bring-up').line()}")
        raise
    finally:
        rig.close()


def _write(session: Session, rig_file: Path, out: Path) -> Outcome:
    accepted: list[confirmed_file.Confirmed] = []
    declined: list[confirmed_file.Confirmed] = []
    for item in session.proposed:
        question = (f"Write {item.name} = {item.toml_value()} ({item.method}; u {item.uncertainty})"
                    " into the confirmed rig file?")
        (accepted if session.operator.confirm(f"write {item.name}", question)
         else declined).append(item)
    if not accepted:
        session.operator.say("Nothing accepted: no confirmed rig file written.")
        return Outcome(session.findings, None, accepted, declined)
    path = confirmed_file.write(rig_file, out, accepted)
    session.operator.say(f"Wrote {len(accepted)} confirmed value(s) to {path}.")
    return Outcome(session.findings, path, accepted, declined)


__all__ = ["Outcome", "check_twin", "connect", "default_out", "routines", "run", "twin_operator"]
