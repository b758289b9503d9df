"""``gelrig --help`` stays fast: building the parser imports no heavy package."""

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Each costs 0.1-1 s to import; commands import them when they run, never the parser.
HEAVY = ("numpy", "scipy", "matplotlib", "nidaqmx", "grpc", "h5py", "PySide6")

PROBE = """
import json, sys
import gelrig.cli
parser = gelrig.cli.build_parser()
parser.format_help()
print(json.dumps(sorted({name.split(".")[0] for name in sys.modules})))
"""


def test_building_the_parser_imports_no_heavy_package():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    proc = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          cwd=ROOT, env=env, check=True)
    loaded = set(json.loads(proc.stdout))
    assert "gelrig" in loaded and "simulators" in loaded  # the probe did build the parser
    assert loaded.isdisjoint(HEAVY), sorted(loaded.intersection(HEAVY))
