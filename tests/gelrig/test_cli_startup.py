"""``gelrig --help`` stays fast: building the parser imports no heavy package."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: Each costs 0.1-1 s to import; commands import them when they run, never the parser.
HEAVY = ("numpy", "scipy", "matplotlib", "nidaqmx", "grpc", "h5py", "PySide6")

PROBE = """
import contextlib, io, json, sys
import gelrig.cli
parser = gelrig.cli.build_parser()
parser.format_help()
argv = sys.argv[1:]
if argv:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        parser.parse_args(argv)
print(json.dumps(sorted(sys.modules)))
"""


def _loaded(*argv: str) -> set[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    proc = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True,
                          cwd=ROOT, env=env, check=True)
    return set(json.loads(proc.stdout))


def test_building_the_parser_imports_no_heavy_package():
    loaded = _loaded()
    assert "gelrig.simulators.serve_options" in loaded  # the probe did build the parser
    tops = {name.split(".")[0] for name in loaded}
    assert tops.isdisjoint(HEAVY), sorted(tops.intersection(HEAVY))
    # the simulators' configurations are loaded only for their own command
    assert "gelrig.simulators.kdc101.config" not in loaded


@pytest.mark.parametrize("name", ["kdc101", "usb6001", "mcr501"])
def test_a_served_simulators_help_imports_no_heavy_package(name):
    """Its options come from the simulator's configuration, which loads without the
    simulator."""
    loaded = _loaded("sim", "serve", name, "--help")
    assert f"gelrig.simulators.{name}.config" in loaded
    tops = {module.split(".")[0] for module in loaded}
    assert tops.isdisjoint(HEAVY), sorted(tops.intersection(HEAVY))
