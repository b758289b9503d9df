"""One identity record for every instrument, flat for run.json."""

from __future__ import annotations

import json

import pytest

from gelrig.instrument.core.identity import Identity


def test_as_dict_is_the_fields_then_the_extras() -> None:
    ident = Identity("Thorlabs", "KDC101", "27000001", "3.0.10", "1",
                     extra={"channels": "1", "serial_number": "27000001"})
    assert ident.as_dict() == {"vendor": "Thorlabs", "model": "KDC101", "serial": "27000001",
                               "firmware": "3.0.10", "hardware": "1", "channels": "1",
                               "serial_number": "27000001"}
    assert json.loads(json.dumps(ident.as_dict())) == ident.as_dict()
    assert str(ident) == "Thorlabs KDC101 serial 27000001 firmware 3.0.10"


def test_unreported_fields_are_empty_and_still_recorded() -> None:
    d = Identity("NI", "USB-6001", "1F2E3D").as_dict()
    assert d["firmware"] == d["hardware"] == ""
    assert str(Identity("NI", "USB-6001", "1F2E3D")) == "NI USB-6001 serial 1F2E3D"


def test_extra_cannot_redefine_a_field() -> None:
    with pytest.raises(ValueError, match="serial"):
        Identity("NI", "USB-6001", "1", extra={"serial": "2"})
