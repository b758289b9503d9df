"""The simulated MCR 501: answers the driver's command table from the shear-cell physics.

It reuses the driver's codec (drivers/mcr501): design.md allows that because independent
clients (pyvisa-py, and a raw socket sending literal bytes) drive it in the tests. The state is
computed lazily from ``clock.now()`` at each request. A trip (torque over range, normal-force
overload) stops all motion at the moment it happens and is answered, instead of the command,
to the next request. A time-limited rotation (``:ROT[dir;rpm;duration]``, ADR 0201) ramps to
rest when its duration runs out unless the same rotation is asked for again before then; the
end is applied at its own time when the next request comes, whoever sends it, so a client
that connects after the one that turned the arm has gone reads where the arm stopped.

A request it cannot take is answered with an ``#ERR`` (10 unknown, 11 bad argument, 13 out of
range); should handling a request ever fail otherwise, the failure is logged (logger
``gelrig.simulators.mcr501``) and answered ``#ERR[11;bad argument (internal ...)]``: no line
ends the server or the client's connection.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque

import numpy as np

from gelrig.drivers.mcr501.codec import RequestError, Values, decode_request, error_line
from gelrig.drivers.mcr501.commands import COMMANDS, MAX_RECORDS, RECORD, STATUS_FLAGS, Command
from gelrig.instrument.core.clock import Clock
from gelrig.simulators.mcr501.config import SimConfig
from gelrig.simulators.mcr501.faults import FaultPlan
from gelrig.simulators.mcr501.physics import ShearCell

log = logging.getLogger("gelrig.simulators.mcr501")

_RPM = 2.0 * math.pi / 60.0
_MOTION = frozenset({"rotate", "rotate_for", "stop", "hold", "set_gap"})
#: Longest duration (s) of a time-limited rotation.
MAX_ROTATION_S = 3600.0
_THOUSAND = np.array(1e3)


def _quantize(value: float, step: float) -> float:
    return round(value / step) * step


class MCR501Simulator:
    """The instrument: :meth:`handle` maps one request line to its reply lines.

    ``faults`` injects line faults for tests. Thread-safe (one lock around each request).
    """

    def __init__(self, clock: Clock, config: SimConfig | None = None):
        self.clock = clock
        self.config = config if config is not None else SimConfig()
        self.faults = FaultPlan()
        self.cell = ShearCell(self.config, clock.now())
        self.mode = "IDLE"
        self.referenced = self.config.start_referenced
        self.requests = 0
        #: The latest request lines, oldest first (for tests and diagnostics).
        self.log: deque[str] = deque(maxlen=200)
        self._reported_trips = 0
        self._fault_flag = False
        # The time-limited rotation in force: when it ends (inf: none) and its set speed.
        self.rotation_end = math.inf
        self._rotation_omega = 0.0
        self.renewals = 0  # time-limited rotations renewed (diagnostics)
        self._stream_rng = np.random.default_rng(self.config.seed)
        self._read_rng = np.random.default_rng([self.config.seed, 1])
        self._lock = threading.Lock()
        self._figures_of: SimConfig | None = None
        self._figures: tuple[np.ndarray, ...] = ()
        self._handlers = {
            "identify": self._identify,
            "status": self._status,
            "zero_gap": self._zero_gap,
            "set_gap": self._set_gap,
            "read_gap": self._read_gap,
            "rotate": self._rotate,
            "rotate_for": self._rotate_for,
            "stop": self._stop,
            "hold": self._hold,
            "read_angle": self._read_angle,
            "read_torque": self._read_torque,
            "read_normal_force": self._read_normal_force,
            "start_stream": self._start_stream,
            "stop_stream": self._stop_stream,
            "read_stream": self._read_stream,
        }
        missing = set(COMMANDS) - set(self._handlers)
        if missing:  # the simulator must serve exactly the table
            raise RuntimeError(f"simulator lacks handlers for {sorted(missing)}")

    # -- the wire ----------------------------------------------------------------------------

    def handle(self, line: str) -> list[str]:
        """The reply lines (without termination) to one request line."""
        with self._lock:
            self.requests += 1
            self.log.append(line.strip())
            try:
                replies = self._handle(line.strip())
            except Exception as exc:  # a bug the request found: logged, the line answered
                log.exception("MCR 501 simulator: handling %r failed", line[:80])
                replies = [error_line(11, f"bad argument (internal {type(exc).__name__})")]
            return self.faults.apply(replies)

    def _handle(self, line: str) -> list[str]:
        now = self.clock.now()
        try:
            command, values = decode_request(line)
        except RequestError as exc:
            return [error_line(exc.code, exc.text)]
        if self.faults.rejects(command.name):
            return [error_line(10, f"unknown command {command.request.key}")]
        self._end_rotation_due(now)
        if command.name == "rotate_for" and self._renews(values, now):
            # The same rotation again: only its end moves. Not a breakpoint of the motion
            # (nothing about it changes), so renewing never changes the physics.
            self.cell.advance(now, ahead=True)
        elif command.name in _MOTION:
            self.cell.commit(now)  # a motion command is a breakpoint: integrate exactly to it
        else:  # a reading: served from the look-ahead while the stream runs
            self.cell.advance(now, ahead=True)
        trip = self._unreported_trip()
        if trip is not None:
            return [trip]
        try:
            return self._handlers[command.name](command, values, now)
        except RequestError as exc:
            return [error_line(exc.code, exc.text)]

    def _unreported_trip(self) -> str | None:
        trips = self.cell.trips
        if len(trips) == self._reported_trips:
            return None
        first = trips[self._reported_trips]
        self._reported_trips = len(trips)
        self.mode = "IDLE"
        self.rotation_end = math.inf  # the trip stopped the motion
        self._fault_flag = True
        return error_line(first.code, f"{first.detail} at t = {first.t:.3f} s; motion stopped")

    # -- commands ----------------------------------------------------------------------------

    def _identify(self, command: Command, values: Values, now: float) -> list[str]:
        model, serial, firmware = self.config.identity
        return [command.reply.encode(model=model, serial=serial, firmware=firmware)]

    def status_flags(self, now: float) -> int:
        flags = 0
        _, omega = self.cell.spin.state(now)
        if self.cell.lift.moving(now):
            flags |= STATUS_FLAGS["gap_moving"]
        if self.referenced:
            flags |= STATUS_FLAGS["gap_referenced"]
        if self.cell.streaming:
            flags |= STATUS_FLAGS["streaming"]
        if omega != self.cell.spin.target:
            flags |= STATUS_FLAGS["accelerating"]
        if self._fault_flag:
            flags |= STATUS_FLAGS["fault"]
        if self.cell.overflowed:
            flags |= STATUS_FLAGS["overflow"]
        return flags

    def _status(self, command: Command, values: Values, now: float) -> list[str]:
        return [command.reply.encode(mode=self.mode, flags=self.status_flags(now))]

    def _ok(self, command: Command) -> list[str]:
        return [command.reply.encode()]

    def _zero_gap(self, command: Command, values: Values, now: float) -> list[str]:
        self.referenced = True
        return self._ok(command)

    def _set_gap(self, command: Command, values: Values, now: float) -> list[str]:
        if not self.referenced:
            raise RequestError(12, "gap not referenced; send :GAPZ[] first")
        gap = float(values["gap_mm"]) * 1e-3
        cfg = self.config
        if not cfg.gap_min <= gap <= cfg.gap_max:
            raise RequestError(
                13, f"gap {gap * 1e3:g} mm outside [{cfg.gap_min * 1e3:g}, {cfg.gap_max * 1e3:g}]"
            )
        self._fault_flag = False
        self.cell.set_gap(now, gap)
        return self._ok(command)

    def _read_gap(self, command: Command, values: Values, now: float) -> list[str]:
        return [command.reply.encode(gap_mm=self.cell.lift.gap(now) * 1e3)]

    def _omega(self, values: Values) -> float:
        """The signed set speed (rad/s) of a rotation request; #ERR 13 beyond the range."""
        rpm = float(values["rpm"])
        if not 0 <= rpm <= self.config.max_rpm:
            raise RequestError(13, f"speed {rpm:g} rpm outside [0, {self.config.max_rpm:g}]")
        sign = 1.0 if values["direction"] == "CW" else -1.0
        return sign * rpm * _RPM

    def _rotate(self, command: Command, values: Values, now: float) -> list[str]:
        omega = self._omega(values)
        self._fault_flag = False
        self.rotation_end = math.inf  # turns until told otherwise
        self.cell.set_speed(now, omega)
        self.mode = "ROT" if omega != 0 else "IDLE"
        return self._ok(command)

    def _rotate_for(self, command: Command, values: Values, now: float) -> list[str]:
        omega = self._omega(values)
        duration = float(values["duration_s"])
        if not 0 < duration <= MAX_ROTATION_S:
            raise RequestError(13, f"duration {duration:g} s, allowed 0 < duration <= "
                                   f"{MAX_ROTATION_S:g} s")
        if self._renews(values, now):
            self.renewals += 1
        else:
            self._fault_flag = False
            self.cell.set_speed(now, omega)
            self.mode = "ROT" if omega != 0 else "IDLE"
        self.rotation_end = now + duration if omega != 0 else math.inf
        self._rotation_omega = omega
        return self._ok(command)

    def _renews(self, values: Values, now: float) -> bool:
        """True if a time-limited rotation request asks for the rotation in force (same
        direction and speed, its end not yet reached): it only moves the end."""
        if not (now < self.rotation_end and self.mode == "ROT"):
            return False
        try:
            omega = self._omega(values)
        except RequestError:
            return False
        return omega == self._rotation_omega and omega == self.cell.spin.target

    def _end_rotation_due(self, now: float) -> None:
        """A time-limited rotation whose end has come ramps to rest from that end on (as a
        :STOP sent at that moment), however late the next request arrives."""
        end = self.rotation_end
        if end > now:
            return
        self.rotation_end = math.inf
        if self.mode == "ROT" and self.cell.spin.target != 0.0:
            self.cell.set_speed(end, 0.0)
            self.mode = "IDLE"

    def _stop(self, command: Command, values: Values, now: float) -> list[str]:
        self.rotation_end = math.inf
        self.cell.set_speed(now, 0.0)
        self.mode = "IDLE"
        return self._ok(command)

    def _hold(self, command: Command, values: Values, now: float) -> list[str]:
        self.rotation_end = math.inf
        self.cell.set_speed(now, 0.0)
        self.mode = "HOLD"
        return self._ok(command)

    def _read_angle(self, command: Command, values: Values, now: float) -> list[str]:
        phi, _ = self.cell.spin.state(now)
        return [command.reply.encode(angle_deg=math.degrees(phi))]

    def measured_torque(self, value: float, rng: np.random.Generator) -> float:
        """Torque as the sensor reports it: noise, then resolution (N m)."""
        noisy = value + self.config.torque_noise * float(rng.standard_normal())
        return _quantize(noisy, self.config.torque_resolution)

    def measured_force(self, value: float, rng: np.random.Generator) -> float:
        """Normal force as the sensor reports it: noise, then resolution (N)."""
        noisy = value + self.config.normal_force_noise * float(rng.standard_normal())
        return _quantize(noisy, self.config.normal_force_resolution)

    def _read_torque(self, command: Command, values: Values, now: float) -> list[str]:
        m = self.measured_torque(self.cell.forces(now).torque, self._read_rng)
        return [command.reply.encode(torque_mnm=m * 1e3)]

    def _read_normal_force(self, command: Command, values: Values, now: float) -> list[str]:
        f = self.measured_force(self.cell.forces(now).f_v, self._read_rng)
        return [command.reply.encode(force_n=f)]

    def _start_stream(self, command: Command, values: Values, now: float) -> list[str]:
        interval = float(values["interval_s"])
        if not 1e-3 <= interval <= 3600.0:
            raise RequestError(13, f"interval {interval:g} s outside [0.001, 3600]")
        self.cell.start_stream(now, interval)
        return self._ok(command)

    def _stop_stream(self, command: Command, values: Values, now: float) -> list[str]:
        self.cell.stop_stream(now)
        return self._ok(command)

    def _read_stream(self, command: Command, values: Values, now: float) -> list[str]:
        samples = self.cell.samples
        batch = samples[:MAX_RECORDS]
        del samples[:MAX_RECORDS]
        lines = [command.reply.encode(count=len(batch), remaining=len(samples))]
        if not batch:
            return lines
        # The noise of each point is drawn torque first, then force, as measured_torque and
        # measured_force would one point at a time: one draw of 2n normals is the same stream.
        # The config's numbers as 0-d arrays: the same float64 products, without numpy's
        # slower path for a Python float operand (a read carries tens of points).
        t_noise, f_noise, t_res, f_res = self._noise_figures()
        z = self._stream_rng.standard_normal(2 * len(batch))
        t, angle, torque, force, gap = np.array(batch, dtype=np.float64).T.copy()
        torque += t_noise * z[0::2]
        force += f_noise * z[1::2]
        # np.rint rounds half to even, as round() does in _quantize; np.degrees is
        # math.degrees (x * (180 / pi)) elementwise.
        torque_mnm = (np.rint(torque / t_res) * t_res) * _THOUSAND
        force_n = np.rint(force / f_res) * f_res
        lines.extend(map(RECORD.row_template.format, t.tolist(), np.degrees(angle).tolist(),
                         torque_mnm.tolist(), force_n.tolist(), (gap * _THOUSAND).tolist()))
        return lines

    def _noise_figures(self) -> tuple[np.ndarray, ...]:
        """Torque and normal-force noise and resolution of the config in force, as 0-d
        arrays (made again if the config was replaced)."""
        cfg = self.config
        if self._figures_of is not cfg:
            self._figures = tuple(np.array(float(v)) for v in (
                cfg.torque_noise, cfg.normal_force_noise, cfg.torque_resolution,
                cfg.normal_force_resolution))
            self._figures_of = cfg
        return self._figures
