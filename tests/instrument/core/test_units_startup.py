"""Units at a start-up (issue 31 item 3): pint without dask, its registry from pint's disk
cache, the same conversions as a registry parsed from the definitions."""

import subprocess
import sys

import pint
import pytest

from gelrig.instrument.core.units import _registry, convert, to_si

CASES = [("0.78 mm", "m"), ("4 kPa", "Pa"), ("2000 s", "s"), ("1 h", "s"), ("12 um", "m"),
         ("0.1 mN", "N"), ("3.5 mN*m", "N*m"), ("2.38e-5 m/s", "m/s"), ("100 Hz", "Hz"),
         ("-0.3 µm", "m"), ("7.1 MPa", "Pa"), ("15 min", "s")]


@pytest.mark.parametrize(("text", "unit"), CASES)
def test_conversions_equal_a_freshly_parsed_registry_to_the_bit(text: str, unit: str) -> None:
    fresh = pint.UnitRegistry()
    assert to_si(text, unit, "x") == float(fresh.Quantity(text).to(unit).magnitude)
    assert convert(2.5, "mm", "m") == float(fresh.Quantity(2.5, "mm").to("m").magnitude)


def test_pint_loads_without_dask_and_the_registry_is_one() -> None:
    assert _registry() is _registry()
    code = ("import sys\n"
            "from gelrig.instrument.core.units import to_si\n"
            "print(to_si('0.78 mm', 'm', 'x'), 'pint' in sys.modules, 'dask' in sys.modules)\n"
            "import dask\n"  # still importable afterwards (a campaign)
            "print(dask.__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.split() == ["0.0007800000000000001", "True", "False", "dask"]
