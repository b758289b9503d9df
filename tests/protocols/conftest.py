"""Rigs for protocol tests: the built-in simulated rigs, built through the real factory."""

import copy
import tomllib

import pytest

from gelrig.factory import build_rig
from gelrig.instrument.core.clock import VirtualClock
from gelrig.protocols.rigfile import default_rig, parse_rig


def rig_table(kind: str) -> dict:
    return tomllib.loads(default_rig(kind).read_text())


@pytest.fixture
def make_rig():
    """make_rig(kind, **section_overrides) -> a connected rig on a fresh VirtualClock."""
    built = []

    def make(kind: str, **overrides: dict):
        table = copy.deepcopy(rig_table(kind))
        for section, values in overrides.items():
            table.setdefault(section, {}).update(values)
        rig = build_rig(parse_rig(table, f"<{kind} test rig>"), VirtualClock())
        built.append(rig)
        return rig

    yield make
    for rig in built:
        rig.close()
