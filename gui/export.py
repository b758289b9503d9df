"""A run's samples as CSV: one row per sample, the step index first, SI columns as recorded.

Only the columns the GUI keeps (those the plots use); the run directory's HDF5 step files
hold the full record.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gelrig.gui.rundata import KEPT, RunData

#: Rows written per block (bounded memory for a 3e6-sample hold).
BLOCK = 100_000


def write_csv(data: RunData, path: Path) -> int:
    """Write ``data`` to ``path``; returns the number of sample rows."""
    steps = data.steps()
    names = [c for c in KEPT if any(c in cols for _s, cols in steps)]
    rows = 0
    with path.open("w", encoding="utf-8", newline="") as out:
        out.write(",".join(["step", *names]) + "\n")
        for step, cols in steps:
            n = min((v.size for v in cols.values()), default=0)
            for start in range(0, n, BLOCK):
                end = min(n, start + BLOCK)
                block = np.full((end - start, len(names) + 1), np.nan)
                block[:, 0] = step.index
                for k, name in enumerate(names, start=1):
                    if name in cols:
                        block[:, k] = cols[name][start:end]
                np.savetxt(out, block, fmt=["%d", *["%.10g"] * len(names)], delimiter=",")
            rows += n
    return rows
