"""One conformance suite for the twin and the instrument (issue 30): ``gelrig check RIG.toml``.

The same read-only checks (and, with ``motion``, one small guarded motion per axis) run
against whatever answers at the rig file's addresses: the simulators for a simulated rig, the
instruments for a real one. So the twin is held to what the instrument does and the
instrument to what gelrig expects, with the same code. Each check is a :class:`Result` (name,
passed, what was seen); nothing here changes a setting the driver did not set on open.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gelrig.instrument.core.errors import GelrigError
from gelrig.protocols.control import RunControl
from gelrig.protocols.manual_motion import guarded
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig

#: The USB-6001's code step (V): 14 bits over +-10 V.
USB6001_STEP = 20.0 / 2**14
#: The small motion of ``--motion`` (m) and the stream interval of the rheometer check (s).
SMALL_MOVE = 0.1e-3
STREAM_INTERVAL = 0.01


@dataclass(frozen=True)
class Result:
    """One check: its name, whether it passed, and what was seen."""

    name: str
    passed: bool
    detail: str

    def line(self) -> str:
        return f"{'PASS' if self.passed else 'FAIL'}  {self.name}: {self.detail}"


Check = Callable[[], tuple[bool, str]]


def _run(name: str, check: Check) -> Result:
    """A check that raises fails with the error's one line."""
    try:
        passed, detail = check()
    except GelrigError as exc:
        return Result(name, False, f"{type(exc).__name__}: {exc}")
    return Result(name, passed, detail)


def _stage_checks(rig: CompressionRig, motion: bool) -> list[Result]:
    stage = rig.stage
    config = rig.stage_caps

    def identity() -> tuple[bool, str]:
        ident = stage.identify()
        ok = ident.model.startswith("KDC101") and str(ident.serial).startswith("27")
        return ok, f"{ident.model} serial {ident.serial} firmware {ident.firmware}"

    def velocity() -> tuple[bool, str]:
        read = getattr(stage, "velocity_params", None)
        if read is None:
            return False, "this stage driver cannot read its velocity parameters back"
        vel = read()
        want = (config.apt_velocity(config.max_velocity_m_s),
                config.apt_acceleration(config.acceleration_m_s2))
        return (vel.max_velocity, vel.acceleration) == want, \
            f"read back {vel.max_velocity} / {vel.acceleration}, set {want[0]} / {want[1]}"

    def limits() -> tuple[bool, str]:
        read = getattr(stage, "limit_switch_params", None)
        if read is None:
            return False, "this stage driver cannot read its soft limits back"
        lim = read()
        want = {config.counts_from_m(config.min_position_m),
                config.counts_from_m(config.max_position_m)}
        got = {lim.cw_soft, lim.ccw_soft}
        return got == want, f"soft limits read back {sorted(got)}, set {sorted(want)}"

    def status() -> tuple[bool, str]:
        s = stage.status()
        ok = s.enabled and s.motor_connected and not s.error and not s.busy
        return ok, (f"0x{s.raw:08X}: enabled {s.enabled}, motor {s.motor_connected}, "
                    f"error {s.error}, busy {s.busy}, homed {s.homed}")

    def position() -> tuple[bool, str]:
        z = stage.position()
        return math.isfinite(z), f"{z * 1e3:.4f} mm"

    results = [_run("stage identity", identity), _run("stage velocity read back", velocity),
               _run("stage soft limits read back", limits), _run("stage status", status),
               _run("stage position", position)]
    if motion:
        results.append(_run("stage small move and back", lambda: _stage_move(rig)))
    return results


def _stage_move(rig: CompressionRig) -> tuple[bool, str]:
    """+0.1 mm (or -0.1 mm near the top) and back under the interlocks: the counts moved,
    and the controller's moving bit against the rig file's direction convention."""
    from gelrig.drivers.kdc101.payloads import Directions

    stage, config = rig.stage, rig.stage_caps
    start = stage.position()
    step = SMALL_MOVE if start + SMALL_MOVE <= config.max_position_m else -SMALL_MOVE
    bits: list[int] = []

    def go() -> None:
        stage.move_by(step, wait=False)
        rig.clock.sleep(0.02)
        bits.append(stage.status().raw)

    control = RunControl()
    moved = guarded(rig, "check move", go, control, toward=step > 0)
    there = stage.position()
    back = guarded(rig, "check move back", lambda: stage.move_to(start, wait=False), control,
                   toward=step < 0)
    if moved.outcome != "done" or back.outcome != "done":
        return False, f"motion {moved.outcome} / {back.outcome}: {moved.reason or back.reason}"
    counts = config.counts_from_m(there - start)
    want = config.counts_from_m(step)
    sign = 1 if step > 0 else -1
    expected_bit = Directions.named(config.direction).moving_bit(sign)
    raw = bits[0] if bits else 0
    ok = abs(counts - want) <= 1 and bool(raw & expected_bit)
    return ok, (f"moved {counts} counts for {want}; status 0x{raw:08X} while moving "
                f"({'has' if raw & expected_bit else 'LACKS'} the {config.direction} "
                f"moving bit 0x{expected_bit:02X})")


def _force_checks(rig: CompressionRig) -> list[Result]:
    force = rig.force

    def identity() -> tuple[bool, str]:
        ident = force.identify()
        return "6001" in ident.model, f"{ident.vendor} {ident.model} serial {ident.serial}"

    def acquisition() -> tuple[bool, str]:
        rig.end_monitoring()
        force.stop()
        force.start(1000.0)
        try:
            block = force.read_block(1000)
        finally:
            force.stop()
        volts = np.asarray(block.volts)
        dt = np.diff(np.asarray(block.t))
        ok = (len(block) == 1000 and bool(np.all(np.isfinite(volts)))
              and not block.any_over_range and bool(np.allclose(dt, 1e-3, rtol=1e-3)))
        levels = np.diff(np.unique(volts))
        step = float(levels[levels > 1e-9].min()) if np.any(levels > 1e-9) else math.nan
        steps_ok = math.isfinite(step) and abs(step / USB6001_STEP - round(
            step / USB6001_STEP)) < 0.01
        return ok and steps_ok, (f"{len(block)} samples at 1 kHz, {volts.mean() * 1e3:.3f} mV "
                                 f"mean, code step {step * 1e3:.4f} mV (14 bit: "
                                 f"{USB6001_STEP * 1e3:.4f} mV)")

    return [_run("force identity", identity), _run("force acquisition 1 s", acquisition)]


def _rheometer_checks(rig: ShearRig) -> list[Result]:
    from gelrig.bringup.rheometer import check_reply
    from gelrig.drivers.mcr501.commands import COMMANDS

    rheo = rig.rheometer

    def identity() -> tuple[bool, str]:
        ident = rheo.identify()
        return "MCR" in ident.model, f"{ident.vendor} {ident.model} serial {ident.serial}"

    def table() -> tuple[bool, str]:
        exchange = getattr(rheo, "exchange", None)
        if exchange is None:
            return False, "the driver cannot send a line as written"
        bad = []
        names = ("identify", "status", "read_gap", "read_angle", "read_torque",
                 "read_normal_force")
        for name in names:
            ok, note = check_reply(COMMANDS[name], exchange(COMMANDS[name].request.encode()))
            if not ok:
                bad.append(f"{name}: {note}")
        return not bad, "; ".join(bad) or f"{len(names)} read-only commands as the table says"

    def stream() -> tuple[bool, str]:
        rheo.start_stream(STREAM_INTERVAL)
        try:
            rig.clock.sleep(0.5)
            points = list(rheo.read_stream())
        finally:
            rheo.stop_stream()
        t = np.array([p.t for p in points])
        ok = len(points) >= 40 and bool(np.all(np.diff(t) > 0))
        return ok, f"{len(points)} points in 0.5 s at {STREAM_INTERVAL:g} s, times increasing"

    def status() -> tuple[bool, str]:
        s = rheo.status()
        return not s.fault, f"mode {s.mode}, gap referenced {s.gap_referenced}, fault {s.fault}"

    return [_run("rheometer identity", identity), _run("rheometer status", status),
            _run("rheometer read-only commands", table), _run("rheometer stream", stream)]


def check_rig(rig: Rig, motion: bool = False) -> list[Result]:
    """Every check of ``rig``'s instruments; ``motion``: also one small guarded motion."""
    if isinstance(rig, CompressionRig):
        return [*_stage_checks(rig, motion), *_force_checks(rig)]
    return _rheometer_checks(rig)


__all__ = ["Result", "check_rig"]
