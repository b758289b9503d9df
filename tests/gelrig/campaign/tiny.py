"""Tiny campaign files for the tests: members of about a second each."""

from __future__ import annotations

from pathlib import Path

#: The paper compression with a 60 s hold at 100 Hz: a member takes about 2 s.
COMPRESSION = """
[campaign]
name = "tiny compression"
protocol = "paper:compression"
replicates = {replicates}

[simulator]
{simulator}

[params]
"step[1].hold" = "60 s"
"step[1].rate" = "100 Hz"
"""

#: The reduced paper ladder: 1 overlap x 2 speeds, short waits (about 4 s a member).
SHEAR = """
[campaign]
name = "tiny shear"
protocol = "paper:shear"
replicates = {replicates}

[simulator]
{simulator}

[params]
"step[1].overlaps" = 1
"step[1].first_overlap" = "0.78 mm"
"step[1].speeds" = [["2.38e-5 m/s", "2.37e-4 m/s"]]
"step[1].wait" = "5 s"
"""


def write(folder: Path, template: str, replicates: int = 2, simulator: str = "",
          name: str = "tiny.toml") -> Path:
    path = folder / name
    path.write_text(template.format(replicates=replicates, simulator=simulator))
    return path
