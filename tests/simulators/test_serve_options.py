"""The light option table of ``gelrig sim serve`` matches the serve modules it stands for."""

import importlib

import pytest

from simulators.serve_options import SERVED


@pytest.mark.parametrize("name", sorted(SERVED))
def test_summary_and_options_are_the_serve_modules_own(name):
    served = SERVED[name]
    module = importlib.import_module(served.module)
    assert served.summary == module.__doc__.strip().splitlines()[0]
    assert module.add_arguments is served.add_arguments
    assert callable(module.run)

