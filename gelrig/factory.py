"""The rig factory: a validated rig file + a clock -> a connected rig of real drivers.

A composition root (design.md): it wires drivers to transports, and for instruments whose
transport is ``simulator`` it starts the simulator first and points the same driver at it
through the instrument's real wire protocol (APT bytes over a pyserial URL, the NI gRPC
service, bracketed ASCII over pyvisa). Nothing imports this module but the entry points.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from typing import TypeVar

from gelrig.drivers.mcr501.driver import MCR501
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.core.errors import ConfigError, InstrumentError
from gelrig.instrument.core.identity import Identity
from gelrig.protocols.rig import CompressionRig, Rig, ShearRig
from gelrig.protocols.rigfile import CompressionRigSpec, Connection, RigSpec, ShearRigSpec

T = TypeVar("T")

log = logging.getLogger(__name__)


def build_rig(spec: RigSpec, clock: Clock, in_process: bool = False) -> Rig:
    """Connect every instrument of ``spec`` (starting simulators as needed). With
    ``in_process`` a simulated force input is reached without its gRPC server (the same
    nidaqmx client and servicer, a direct call): the twin's speed-up."""
    if isinstance(spec, ShearRigSpec):
        return _shear(spec, clock)
    return _compression(spec, clock, in_process)


def twin_spec(spec: RigSpec) -> RigSpec:
    """``spec`` with every instrument replaced by its simulator under the same configuration
    (limits, caps, travel, calibration); the ``[simulator]`` sample where the file gives one,
    else the nominal one (its defaults). The rheometer is reached in-process (``link =
    "direct"``): the same driver code and lab times as over TCP, without the sockets."""
    if isinstance(spec, ShearRigSpec):
        return dataclasses.replace(
            spec, rheometer=dataclasses.replace(spec.rheometer, transport="simulator"),
            simulator=dataclasses.replace(spec.simulator, link="direct"))
    return dataclasses.replace(
        spec, stage=dataclasses.replace(spec.stage, transport="simulator"),
        force=dataclasses.replace(spec.force, transport="simulator"))


def build_twin(spec: RigSpec) -> Rig:
    """The rig's twin on a fresh virtual clock: what ``gelrig plan`` rehearses on."""
    from gelrig.instrument.core import wire
    from gelrig.instrument.core.clock import VirtualClock

    with wire.suspended():  # a rehearsal is not part of a recorded session (issue 30)
        return build_rig(twin_spec(spec), VirtualClock(), in_process=True)


def _record(identity: Identity, transport: str, address: str) -> dict[str, str]:
    """An instrument's entry in run.json: who it is, and how it was reached."""
    return {**identity.as_dict(), "transport": transport, "address": address}


def _connect(entry: Connection, name: str, source: str, what: str,
             connect: Callable[[], T]) -> T:
    """Run ``connect``; an instrument that cannot be reached becomes a ConfigError naming the
    rig file field that holds its address and what was tried (exit code 2)."""
    try:
        return connect()
    except InstrumentError as exc:
        field = f"[{name}] address" if entry.address else f"[{name}] transport"
        value = entry.address or entry.transport
        detail = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(field, value, f"cannot connect: tried {what} ({detail}); check the "
                          "address, the cable and that the instrument is on", source) from None


def _close_all(closers: list[Callable[[], None]]) -> None:
    for closer in reversed(closers):
        try:
            closer()
        except Exception:
            log.exception("cleanup failed")


def _shear(spec: ShearRigSpec, clock: Clock) -> ShearRig:
    from gelrig.simulators.mcr501.link import DirectLink
    from gelrig.simulators.mcr501.server import SimulatorServer
    from gelrig.simulators.twins.shear import shear_simulator

    entry, truth = spec.rheometer, spec.simulator
    twin: object | None = None
    closers: list[Callable[[], None]] = []
    try:
        if entry.simulated:
            sim = shear_simulator(clock, truth, entry.config)
            twin = sim
            if truth.link == "direct":
                driver = MCR501(DirectLink(sim), clock, entry.config)
                where = "in-process link"
            else:
                server = SimulatorServer(sim).start()
                closers.append(server.close)
                driver = MCR501(server.resource, clock, entry.config)
                where = server.resource
        else:
            driver = MCR501(entry.address, clock, entry.config, backend=entry.backend)
            where = entry.address
        closers.insert(0, driver.close)
        tried = "the simulator" if entry.simulated else f"VISA {where} ({entry.backend})"
        identity = _connect(entry, "rheometer", spec.source, tried,
                            lambda: (driver.open(), driver.identify())[1])
        identities: dict[str, object] = {
            "rheometer": _record(identity, entry.transport, where)}
    except BaseException:
        _close_all(closers)
        raise
    rig = ShearRig(driver, clock, spec.limits, identities, entry.simulated, closers[1:])
    rig.twin = twin
    return rig


def _compression(spec: CompressionRigSpec, clock: Clock, in_process: bool = False
                 ) -> CompressionRig:
    from gelrig.drivers.kdc101 import KDC101
    from gelrig.drivers.usb6001.sensor import Usb6001ForceSensor
    from gelrig.simulators.kdc101 import register, unregister
    from gelrig.simulators.twins.compression import CompressionTwin

    stage_entry, force_entry = spec.stage, spec.force
    chain = force_entry.chain
    closers: list[Callable[[], None]] = []
    identities: dict[str, object] = {}
    try:
        if force_entry.simulated and not stage_entry.simulated:
            raise ConfigError("force.transport", "simulator", "a simulated force needs "
                              "the simulated stage (its plate drives the contact)", spec.source)
        # The simulated instruments, coupled by the twin (the stage follows the rig's
        # direction convention, ADR 0100; its plate drives the contact the load cell reads).
        twin = (CompressionTwin.build(clock, spec.simulator, stage_entry.config, chain,
                                      force_entry.config) if stage_entry.simulated else None)
        if twin is not None:
            name = f"gelrig-{id(twin.stage):x}"
            address = register(twin.stage, name)
            closers.append(lambda: unregister(name))
        else:
            address = stage_entry.address
        stage = KDC101(address, stage_entry.config, clock)
        closers.append(stage.close)
        tried = "the simulator" if stage_entry.simulated else f"serial port {address}"
        identity = _connect(stage_entry, "stage", spec.source, tried,
                            lambda: (stage.open(), stage.identify())[1])
        identities["stage"] = _record(identity, stage_entry.transport, address)
        if force_entry.simulated:
            assert twin is not None
            device = twin.force
            if in_process:
                import nidaqmx

                from gelrig.simulators.usb6001.inprocess import InProcessChannel

                force_address = "in-process"
                options: str | nidaqmx.GrpcSessionOptions = nidaqmx.GrpcSessionOptions(
                    grpc_channel=InProcessChannel(device), session_name="")
            else:
                from gelrig.simulators.usb6001.server import start_server  # gRPC server

                server = start_server(device)
                closers.append(server.stop)
                force_address = options = f"grpc://{server.address}"
        else:
            force_address = force_entry.address if force_entry.transport == "grpc" else "local"
            options = force_address
        force = Usb6001ForceSensor(options, force_entry.config, chain, clock)
        closers.append(force.close)
        tried = {"grpc": f"the NI gRPC Device Server at {force_address}",
                 "nidaqmx": "NI-DAQmx on this computer"}.get(force_entry.transport,
                                                             "the simulator")
        identity = _connect(force_entry, "force", spec.source, tried,
                            lambda: (force.open(), force.identify())[1])
        identities["force"] = _record(identity, force_entry.transport, force_address)
    except BaseException:
        _close_all(closers)
        raise
    # stage.close and force.close run in CompressionRig.close; the rest (servers) after them
    hooks = [c for c in closers if c not in (stage.close, force.close)]
    rig = CompressionRig(stage, force, clock, spec.limits, identities, spec.simulated,
                         list(reversed(hooks)))
    rig.twin = twin
    return rig


__all__ = ["build_rig", "build_twin", "twin_spec"]
