"""The compression rig's twin: the simulated KDC101 carries the plate into the simulated sphere,
whose force the simulated USB-6001 reads through the load-cell chain, on one clock.

The coupling is the plate position, the one function the contact needs
(:mod:`gelrig.instrument.physics.plate_contact`)::

    plate(t) = extension(t) - home_offset        overlap(t) = plate(t) - first_touch

``extension`` is the actuator's extension from its home switch (the stage simulator's
trajectory, exact at any time); less the home offset it is the position of the homed axis,
the frame the rig file's ``first_touch`` and the protocols' positions are in. It is fixed to
the hardware: it does not jump when homing re-zeros the encoder counter (before homing the
driver's positions are in the power-on frame, the plate's are not). The APT direction
convention (``[stage] direction``, ADR 0100) changes which wire code moves the plate which
way, never where the plate is: a move to a position reaches the same plate whatever the
convention. A larger position moves the plate into the sphere.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from gelrig.instrument.contracts.daq import Usb6001Config
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.contracts.stage import (
    FORWARD_IS_NEGATIVE,
    FORWARD_IS_POSITIVE,
    StageConfig,
)
from gelrig.instrument.core.clock import Clock
from gelrig.instrument.physics.contact import FloatArray
from gelrig.instrument.physics.plate_contact import PlateSphereContact
from gelrig.instrument.physics.truth import CompressionTruth
from gelrig.simulators.kdc101.config import SimConfig
from gelrig.simulators.kdc101.device import KDC101Simulator
from gelrig.simulators.usb6001.config import SIM_OFFSET
from gelrig.simulators.usb6001.device import DOCUMENTED, DaqTiming, DeviceSpec, SimulatedUsb6001
from gelrig.simulators.usb6001.rig import compression_daq
from gelrig.simulators.usb6001.signals import LoadCellSignal


class StagePlate:
    """The plate's position (m, homed axis) at an array of times: the stage simulator's
    extension less its home offset. What the contact of the twin is driven by."""

    def __init__(self, stage: KDC101Simulator):
        self.stage = stage
        self.home = stage.config.home_offset_m

    def __call__(self, ts: FloatArray) -> FloatArray:
        return self.stage.positions_at(ts) - self.home


def stage_simulator(clock: Clock, stage: StageConfig, truth: CompressionTruth | None = None
                    ) -> KDC101Simulator:
    """The simulated KDC101 + Z825B of a rig file's ``[stage]`` table: the actuator's own
    hardware (its true encoder scale, travel, power-on state), following the table's direction
    convention (ADR 0100), with the truth's status-update period and reply latency."""
    if truth is None:
        return KDC101Simulator(clock, SimConfig(direction=stage.direction))
    config = SimConfig(direction=true_direction(stage, truth), timing=truth.timing,
                       update_period_s=truth.stage_update_period,
                       reply_latency_s=truth.stage_reply_latency)
    if truth.counts_per_mm is not None:
        config = dataclasses.replace(config, counts_per_mm=truth.counts_per_mm)
    return KDC101Simulator(clock, config)


def true_direction(stage: StageConfig, truth: CompressionTruth) -> str:
    """The simulated controller's real direction convention: the truth's ``direction`` (+1:
    APT forward is larger counts), else the rig file's ``[stage] direction``."""
    if truth.direction is None:
        return stage.direction
    return FORWARD_IS_POSITIVE if truth.direction > 0 else FORWARD_IS_NEGATIVE


def true_chain(chain: LoadCellChain, truth: CompressionTruth) -> LoadCellChain:
    """The simulated load-cell chain: the rig file's, with the truth's real rated output
    where it gives one, and the simulated conditioner's offset
    (:data:`~gelrig.simulators.usb6001.config.SIM_OFFSET`, so that a missing tare shows)."""
    rated = chain.rated_output if truth.rated_output is None else truth.rated_output
    return dataclasses.replace(chain, offset=chain.offset + SIM_OFFSET, rated_output=rated)


def force_simulator(clock: Clock, plate: StagePlate, truth: CompressionTruth,
                    chain: LoadCellChain, daq: Usb6001Config | None = None
                    ) -> SimulatedUsb6001:
    """The simulated USB-6001 whose input sees the load cell under the sphere of ``truth``,
    pressed by ``plate``.

    ``chain`` is the rig file's ``[force.chain]``; the simulated one is :func:`true_chain`
    (the truth's rated output, an offset), and the truth's force noise (white rms, drift,
    correlated part) reaches the input through the true sensitivity.
    ``daq`` is the ``[force]`` table: the device answers to its name, the load cell is wired to
    its channel.
    """
    daq = daq or Usb6001Config()
    real = true_chain(chain, truth)
    return compression_daq(
        clock, plate, first_touch=truth.first_touch, vectorized=True,
        sphere_radius=truth.sphere_diameter / 2, seed=int(truth.seed),
        chain=real, noise_rms=truth.noise * real.sensitivity,
        noise_drift=truth.noise_drift * real.sensitivity,
        noise_correlated=(truth.noise_correlated * real.sensitivity, truth.noise_tau),
        material=truth.material,
        unloading=truth.unloading, channel=daq.channel,
        spec=DeviceSpec(name=daq.device, timing=daq_timing(truth)))


def daq_timing(truth: CompressionTruth) -> DaqTiming:
    """How the truth's simulated USB-6001 meets the host's clock: drift, USB transfers; the
    ``timing`` preset's values where the truth gives none (ADR 0242)."""
    base = DOCUMENTED if truth.timing == "documented" else DaqTiming()

    def given(value: float | None, preset: float) -> float:
        return preset if value is None else value

    return DaqTiming(given(truth.daq_drift_ppm, base.drift_ppm),
                     given(truth.daq_latency, base.latency),
                     given(truth.daq_jitter, base.jitter),
                     int(given(truth.daq_transfer, base.transfer)), int(truth.seed))


@dataclass(frozen=True)
class CompressionTwin:
    """The simulated instruments of a compression rig, coupled through :attr:`plate`."""

    stage: KDC101Simulator
    plate: StagePlate
    force: SimulatedUsb6001
    #: The force input's channel the load cell is wired to.
    channel: str = "ai0"

    @classmethod
    def build(cls, clock: Clock, truth: CompressionTruth, stage: StageConfig,
              chain: LoadCellChain, daq: Usb6001Config | None = None) -> CompressionTwin:
        """The twin of a rig file: its ``[simulator]`` truth, its ``[stage]`` table (the
        direction convention), its ``[force.chain]`` and its ``[force]`` table (device and
        channel)."""
        stage_sim = stage_simulator(clock, stage, truth)
        plate = StagePlate(stage_sim)
        return cls(stage_sim, plate, force_simulator(clock, plate, truth, chain, daq),
                   (daq or Usb6001Config()).channel)

    @property
    def signal(self) -> LoadCellSignal:
        """The force input's signal: the plate-sphere contact through the load-cell chain."""
        signal = self.force.sources[self.channel]
        assert isinstance(signal, LoadCellSignal)
        return signal

    @property
    def contact(self) -> PlateSphereContact:
        """The plate-sphere contact the load cell carries."""
        return self.signal.contact


__all__ = ["CompressionTwin", "StagePlate", "daq_timing", "force_simulator", "stage_simulator",
           "true_chain", "true_direction"]
