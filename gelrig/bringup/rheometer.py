"""MCR 501 bring-up: every command of the (unconfirmed) table sent, its reply checked against
the table and the differences shown; the gap referenced; torque and normal-force zero and noise.

The table (drivers/mcr501/commands.py, ADR 0020) is the project's reconstruction: here each
entry meets the instrument. Requests are the table's own encodings with harmless arguments
(the lift moves up 1 mm and back, the arm turns at 0.1 rpm for 1 s, an unbounded rotation is
sent at 0 rpm and stopped at once); each motion is asked for first and watched under the
rig's interlocks and Stop. The torque and normal-force noise are written to the rig file's
``[rheometer]`` table (the twin's noise from then on); the table lives in code, and a
difference found is a change to the table (and its simulator) to make by review.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gelrig.bringup.common import Session
from gelrig.drivers.mcr501.commands import COMMANDS, ERROR, Command
from gelrig.instrument.core.errors import GelrigError
from gelrig.protocols.rig import ShearRig

#: The order the table is walked in, with each request's arguments (None: no motion asked).
SAFE_ROTATION_RPM, SAFE_ROTATION_S = 0.1, 1.0
GAP_STEP = 1e-3
#: The zero-and-noise record: its stream interval and length (s).
NOISE_INTERVAL, NOISE_SECONDS = 0.01, 10.0


@dataclass(frozen=True)
class Check:
    """One command sent and what came back."""

    name: str
    request: str
    reply: list[str]
    ok: bool
    note: str


def check_reply(command: Command, lines: list[str]) -> tuple[bool, str]:
    """Whether ``lines`` are the reply the table expects for ``command``; a note if not."""
    first = lines[0] if lines else ""
    if ERROR.match(first) is not None:
        return False, f"error reply {first}"
    if command.reply.match(first) is None:
        return False, f"expected {command.reply.key}[{_shape(command)}], got {first!r}"
    if command.records is not None:
        bad = [ln for ln in lines[1:] if command.records.match(ln) is None]
        if bad:
            return False, f"record {bad[0]!r} is not {command.records.key}[...]"
    return True, ""


def _shape(command: Command) -> str:
    shape = command.reply.shape
    return shape if isinstance(shape, str) else ";".join(f.name for f in shape)


class RheometerBringup:
    """The MCR 501's routines: :meth:`command_table`, then :meth:`zero_and_noise`."""

    def __init__(self, session: Session):
        rig = session.rig
        assert isinstance(rig, ShearRig)
        self.s = session
        self.rig = rig
        self.checks: list[Check] = []

    def run(self) -> None:
        self.command_table()
        self.zero_and_noise()

    def _send(self, name: str, **values: object) -> list[str]:
        command = COMMANDS[name]
        request = command.request.encode(**values)
        exchange = getattr(self.rig.rheometer, "exchange", None)
        if exchange is None:
            raise GelrigError("this rheometer driver cannot send a line as written; the "
                              "command table cannot be checked")
        lines: list[str] = exchange(request)
        ok, note = check_reply(command, lines)
        self.checks.append(Check(name, request, lines, ok, note))
        return lines

    def _settle(self, seconds: float = 60.0) -> None:
        end = self.rig.clock.now() + seconds
        while self.rig.rheometer.status().busy and self.rig.clock.now() < end:
            self.rig.clock.sleep(0.05)

    def command_table(self) -> None:
        if not self.s.ask("rheometer.commands", "MCR 501 command table: every command is sent "
                          "with harmless arguments and its reply checked against the table. "
                          "The gap is referenced, the lift moves up 1 mm and back, the arm "
                          "turns 0.1 rpm for 1 s. Take the lower sphere out first."):
            return
        for name in ("identify", "status", "read_angle", "read_torque", "read_normal_force"):
            self._send(name)
        self.s.move("gap reference", lambda: self._send("zero_gap"), toward=False)
        self._settle()
        reply = self._send("read_gap")
        decoded = COMMANDS["read_gap"].reply.decode(reply[0])
        gap = float(decoded["gap_mm"]) if decoded else None
        if gap is not None:
            up = gap + GAP_STEP * 1e3
            self.s.move("gap up 1 mm", lambda: self._send("set_gap", gap_mm=up), toward=False)
            self._settle()
            self.s.move("gap back", lambda: self._send("set_gap", gap_mm=gap), toward=True)
            self._settle()
        self.s.move("rotation 0.1 rpm for 1 s", lambda: self._send(
            "rotate_for", direction="CW", rpm=SAFE_ROTATION_RPM, duration_s=SAFE_ROTATION_S),
            toward=True)
        self._send("stop")
        self._send("rotate", direction="CW", rpm=0.0)
        self._send("stop")
        self._send("hold")
        self._send("start_stream", interval_s=0.05)
        self.rig.clock.sleep(0.2)
        self._send("read_stream")
        self._send("stop_stream")
        bad = [c for c in self.checks if not c.ok]
        self.s.found(f"command table: {len(self.checks)} exchanges over "
                     f"{len({c.name for c in self.checks})} commands of {len(COMMANDS)}; "
                     f"{len(bad)} differ from the table")
        for c in bad:
            self.s.found(f"  {c.name}: sent {c.request}: {c.note}")

    def zero_and_noise(self) -> None:
        if not self.s.ask("rheometer.noise", f"MCR 501 zero and noise: nothing touching the "
                          f"arm; torque and normal force are streamed for {NOISE_SECONDS:g} s "
                          "(no motion)."):
            return
        rheo = self.rig.rheometer
        rheo.start_stream(NOISE_INTERVAL)
        try:
            self.rig.clock.sleep(NOISE_SECONDS)
            block = rheo.read_stream()
        finally:
            rheo.stop_stream()
        torque = np.array([p.torque for p in block])
        force = np.array([p.normal_force for p in block])
        self.s.found(f"torque zero {np.mean(torque) * 1e6:.4g} uN*m, noise "
                     f"{np.std(torque) * 1e6:.4g} uN*m rms; normal force zero "
                     f"{np.mean(force) * 1e3:.4g} mN, noise {np.std(force) * 1e3:.4g} mN rms "
                     f"({torque.size} points)")
        method = (f"standard deviation of {torque.size} points streamed every "
                  f"{NOISE_INTERVAL * 1e3:g} ms, nothing touching the arm")
        for key, values, unit, scale in (("torque_noise", torque, "uN*m", 1e6),
                                         ("normal_force_noise", force, "mN", 1e3)):
            rms = float(np.std(values))
            u = rms / np.sqrt(2 * max(values.size - 1, 1))
            self.s.propose("rheometer", key, f"{rms * scale:.4g} {unit}", method,
                           f"{u * scale:.2g} {unit} (k=1)")


__all__ = ["Check", "RheometerBringup", "check_reply"]
