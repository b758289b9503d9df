"""The MCR 501 lifecycle (ADR 0050): no I/O before open(), idempotent close, and Ctrl-C while
the arm turns sends stop over the wire before the KeyboardInterrupt propagates."""

from __future__ import annotations

from typing import Any

import pytest

from gelrig.drivers.mcr501 import MCR501
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import Disconnected
from gelrig.simulators.mcr501 import MCR501Simulator, SimConfig
from gelrig.simulators.mcr501.link import DirectLink
from tests.drivers.mcr501_harness import rig


class RecordingLink(DirectLink):
    """DirectLink that remembers every line sent."""

    def __init__(self, simulator: MCR501Simulator):
        super().__init__(simulator)
        self.sent: list[str] = []

    def write_line(self, line: str) -> None:
        self.sent.append(line)
        super().write_line(line)


def test_constructing_does_no_io() -> None:
    drv = MCR501("TCPIP0::127.0.0.1::1::SOCKET", VirtualClock())  # nobody listens there
    assert not drv.is_open
    with pytest.raises(Disconnected, match="not open"):
        drv.torque()
    with pytest.raises(Disconnected):
        drv.open()
    assert not drv.is_open
    drv.close()


def test_open_identifies_and_close_is_idempotent() -> None:
    clock = VirtualClock()
    link = RecordingLink(MCR501Simulator(clock, SimConfig()))
    drv = MCR501(link, clock)
    assert link.sent == []
    assert drv.open() is drv
    assert link.sent == ["#VERS[?]"]
    assert drv.identity is not None and drv.identity.model == "MCR501"
    drv.open()  # already open: a no-op
    assert link.sent == ["#VERS[?]"]
    drv.close()
    drv.close()
    assert not drv.is_open


def test_the_context_manager_opens_and_closes() -> None:
    clock = VirtualClock()
    sim = MCR501Simulator(clock, SimConfig(start_referenced=True))
    with MCR501(DirectLink(sim), clock) as drv:
        assert drv.is_open
        drv.rotate(1e-3)
        assert drv.maybe_rotating
    assert not drv.is_open
    assert sim.log[-1] == ":STOP[]"  # closing while turning stops the arm


def test_ctrl_c_during_rotation_stops_the_arm_first(rm: Any,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    with rig(rm, SimConfig(start_referenced=True)) as r:
        r.drv.rotate(1e-3)
        r.turn(0.9)  # the torque request below is then not preceded by a renewal
        link = r.drv._transport
        real_read = link.read_line
        calls = {"n": 0}

        def read_line() -> str:
            calls["n"] += 1
            if calls["n"] == 1:
                raise KeyboardInterrupt  # Ctrl-C while the driver waits for the torque reply
            return real_read()

        monkeypatch.setattr(link, "read_line", read_line)
        with pytest.raises(KeyboardInterrupt):
            r.drv.torque()
        assert list(r.sim.log)[-2:] == [":TORQ[?]", ":STOP[]"]
        assert not r.drv.maybe_rotating
        assert r.arm_stopped()
        assert r.drv.identify().model == "MCR501"  # the unread torque reply was drained
