"""Shared fixtures of the driver tests."""

from collections.abc import Iterator
from typing import Any

import pytest

from gelrig.drivers.mcr501 import open_resource_manager


@pytest.fixture(scope="module")
def rm() -> Iterator[Any]:
    """A pyvisa resource manager on the pyvisa-py backend."""
    manager = open_resource_manager("@py")
    yield manager
    manager.close()
