"""The compression rig's twin: the stage simulator's plate reaches the load cell's force.

The stage is driven by gelrig's KDC101 driver over ``kdc101sim://`` in virtual time; the force
is read off the twin's load-cell signal (the contact the USB-6001 simulator samples).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from gelrig.drivers.kdc101 import KDC101
from gelrig.instrument.contracts.daq import Usb6001Config
from gelrig.instrument.contracts.loadcell import LoadCellChain
from gelrig.instrument.contracts.stage import DIRECTIONS, StageConfig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.physics.contact import Material, hertz_prefactor
from gelrig.instrument.physics.truth import CompressionTruth
from gelrig.simulators.kdc101 import KDC101Simulator, SimConfig, register, unregister
from gelrig.simulators.twins.compression import CompressionTwin, StagePlate
from gelrig.simulators.usb6001.config import SIM_OFFSET

#: Purely elastic: the force is Hertz at the overlap of the moment, whatever the history.
ELASTIC = Material.of(5e3)
TOUCH = 6.2e-3
_names = itertools.count()


def _truth(**changes: object) -> CompressionTruth:
    values: dict[str, object] = {"first_touch": TOUCH, "noise": 0.0, "material": ELASTIC}
    return CompressionTruth(**{**values, **changes})


@contextmanager
def _stage(clock: VirtualClock, sim: KDC101Simulator, direction: str) -> Iterator[KDC101]:
    name = f"twin{next(_names)}"
    stage = KDC101(register(sim, name), StageConfig(direction=direction), clock).open()
    try:
        yield stage
    finally:
        stage.close()
        unregister(name)


def _force_now(twin: CompressionTwin, clock: VirtualClock) -> float:
    """The true force on the cell now (one sample of the contact)."""
    return float(twin.signal.force(clock.now(), 1e-3, 1)[0])


@pytest.mark.parametrize("direction", DIRECTIONS)
def test_a_move_into_the_sphere_gives_the_hertz_force_at_the_overlap(direction: str) -> None:
    clock = VirtualClock()
    twin = CompressionTwin.build(clock, _truth(), StageConfig(direction=direction),
                                 LoadCellChain())
    assert twin.stage.config.direction == direction  # the controller follows the rig file
    with _stage(clock, twin.stage, direction) as stage:
        stage.home()
        stage.move_to(TOUCH - 0.2e-3)
        assert _force_now(twin, clock) == 0.0  # short of the sphere: no force
        depth = 0.5e-3
        stage.move_to(TOUCH + depth)  # larger positions press the plate into the sphere
        t = clock.now()
        assert twin.plate(np.array([t]))[0] == pytest.approx(stage.position(), abs=1e-7)
        assert twin.contact.overlap(np.array([t]))[0] == pytest.approx(depth, abs=1e-7)
        radius = _truth().sphere_diameter / 2
        hertz = hertz_prefactor(radius, ELASTIC.nu) * ELASTIC.g_e * depth**1.5
        assert _force_now(twin, clock) == pytest.approx(hertz, rel=1e-3)


def test_the_plate_is_the_homed_axis_and_does_not_jump_when_homing_rezeros() -> None:
    clock = VirtualClock()
    home = 0.5e-3
    sim = KDC101Simulator(clock, SimConfig(home_offset_m=home))
    plate = StagePlate(sim)
    t0 = clock.now()
    # power-on: the plate is the extension (5 mm) less the home offset; the counter reads 0
    assert plate(np.array([t0]))[0] == pytest.approx(sim.config.start_position_m - home)
    with _stage(clock, sim, "forward_is_negative") as stage:
        assert stage.position() == pytest.approx(0.0, abs=1e-7)
        stage.home()
        assert stage.position() == pytest.approx(0.0, abs=1e-7)
        assert plate(np.array([clock.now()]))[0] == pytest.approx(0.0, abs=1e-7)
        stage.move_to(3e-3)
        t = clock.now()
        # after homing the driver's axis and the plate agree; the plate's past is unchanged
        assert plate(np.array([t]))[0] == pytest.approx(stage.position(), abs=1e-7)
        assert plate(np.array([t0]))[0] == pytest.approx(sim.config.start_position_m - home)
        assert sim.position_at(t) == pytest.approx(3e-3 + home, abs=1e-7)


def test_the_truth_and_the_chain_reach_the_input() -> None:
    chain = LoadCellChain(offset=0.1, gain=500.0)
    truth = _truth(noise=2e-4, seed=7, unloading="mdr", sphere_diameter=20e-3)
    twin = CompressionTwin.build(VirtualClock(), truth, StageConfig(), chain,
                                 Usb6001Config(device="Dev2", channel="ai3"))
    signal = twin.signal
    assert twin.force.sources["ai3"] is signal and twin.force.spec.name == "Dev2"
    # the simulated conditioner's offset is off the nominal one, so a missing tare shows
    assert signal.chain.offset == pytest.approx(0.1 + SIM_OFFSET)
    assert signal.chain.sensitivity == chain.sensitivity
    assert signal.noise_rms == pytest.approx(2e-4 * chain.sensitivity)
    contact = twin.contact
    assert (contact.first_touch, contact.sphere_radius, contact.material) == (TOUCH, 10e-3,
                                                                              ELASTIC)
    assert type(contact._contact).__name__ == "MdrContact"


def test_the_same_seed_gives_the_same_samples() -> None:
    def record(seed: int) -> np.ndarray:
        clock = VirtualClock()
        twin = CompressionTwin.build(clock, _truth(noise=2e-4, seed=seed), StageConfig(),
                                     LoadCellChain())
        return twin.signal.volts(0.0, 1e-3, 200)

    assert np.array_equal(record(3), record(3))
    assert not np.array_equal(record(3), record(4))


# The hidden facts (issue 30): the simulated hardware is what the truth says, the driver
# uses what the rig file believes.

def test_the_stage_moves_by_its_true_scale_not_the_rig_files():
    clock = VirtualClock()
    truth = _truth(counts_per_mm=34304.0)
    twin = CompressionTwin.build(clock, truth, StageConfig(), LoadCellChain())
    believed = StageConfig()  # 34554.96 counts/mm
    with _stage(clock, twin.stage, believed.direction) as stage:
        stage.home()
        start = float(twin.plate(np.array([clock.now()]))[0])
        stage.move_by(1e-3)
        moved = float(twin.plate(np.array([clock.now()]))[0]) - start
    assert moved == pytest.approx(round(34554.96) / 34304.0 * 1e-3, rel=1e-4)


@pytest.mark.parametrize(("sign", "word"), [(1, "forward_is_positive"),
                                            (-1, "forward_is_negative")])
def test_the_controllers_true_direction_follows_the_truth(sign, word):
    twin = CompressionTwin.build(VirtualClock(), _truth(direction=sign),
                                 StageConfig(direction="forward_is_negative"), LoadCellChain())
    assert twin.stage.config.direction == word


def test_the_load_cell_outputs_its_true_rated_output_and_a_dead_load():
    chain = LoadCellChain()  # believes 2 mV/V
    twin = CompressionTwin.build(VirtualClock(), _truth(rated_output=2.06e-3), StageConfig(),
                                 chain)
    assert twin.signal.chain.rated_output == pytest.approx(2.06e-3)
    twin.signal.dead_load = 1.0
    volts = twin.signal.volts(0.0, 1e-3, 2000)
    true_sens = 2.06e-3 * chain.excitation * chain.gain / chain.capacity
    assert float(volts[-1]) == pytest.approx(SIM_OFFSET + true_sens, rel=1e-6)
