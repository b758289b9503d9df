"""Issue 26 item 4: the recipe warnings (ADR 0261) through the whole simulated rig and
``gelrig analyze``: simulator, wire, drivers, runner, recorder, analysis, summary.

- a hold shorter than the fitted tau (the compression twin's tau is 1413 s; the holds 60 s);
- a held overlap within 20x first touch's standard error (strain 2e-4: about 1 um);
- an anisotropic ladder fit (the shear twin's F_v with its own G_1; slow: the model fit).
The unit tests of ``hold_warnings`` / ``ladder_warnings`` test the rules; these, that a run
shows them where a scientist reads the summary.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from gelrig.cli import main
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run
from tests.gelrig import paper_ladder
from tests.gelrig.test_analyze_compression import steps

SHORT = "the hold (60 s) is shorter than the fitted tau"
NEAR_TOUCH = "is within 20x the resolution of first touch"
ANISOTROPIC = "F_h and F_v have different moduli"


def compression_run(path: Path, strain: float) -> RunDirectory:
    """The paper's contact search, then a ramp to ``strain`` and a 60 s hold (one term)."""
    from gelrig.protocols.rigfile import default_rig

    rig = path / "rig.toml"
    rig.write_text(re.sub(r"(?m)^seed = \d+", "seed = 3", default_rig("compression").read_text()))
    table = steps("60 s")
    table[1].update(strain=strain, terms=1)
    protocol = parse_protocol({"protocol": {"name": "warnings", "rig": "compression"},
                               "step": table})
    spec = load_rig(rig)
    run = RunDirectory.create(path / "run", {"protocol": protocol.table, "rig": spec.table})
    state, _ = record_run(protocol, spec, VirtualClock(), run, show=False)
    assert state is RunState.COMPLETED
    return run


def analyze(capsys: pytest.CaptureFixture, run: RunDirectory, out: Path, *options: str) -> str:
    assert main(["analyze", str(run.path), "--out", str(out), *options]) in (0, 1)
    printed = capsys.readouterr().out
    assert (out / "report.html").is_file() or any(out.glob("*.html"))
    return printed


def warnings(printed: str) -> list[str]:
    return [line.strip() for line in printed.splitlines() if "WARNING:" in line]


def test_a_short_hold_at_the_paper_strain_warns_of_tau_only(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture
                                                             ) -> None:
    printed = analyze(capsys, compression_run(tmp_path, 0.06), tmp_path / "out")
    found = warnings(printed)
    assert any(SHORT in w for w in found), printed
    assert not any(NEAR_TOUCH in w for w in found), found


def test_an_overlap_near_first_touchs_resolution_warns(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture) -> None:
    printed = analyze(capsys, compression_run(tmp_path, 2e-4), tmp_path / "out")
    found = warnings(printed)
    assert any(NEAR_TOUCH in w for w in found), printed
    # the report says it too, as a note
    html = "".join(p.read_text() for p in (tmp_path / "out").glob("*.html"))
    assert "Warning: the held overlap" in html


@pytest.mark.slow
def test_an_anisotropic_ladder_fit_warns_that_mu_from_the_force_ratio_is_biased(
        tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The shear twin with F_v's G_1 at 16 kPa (F_h's 20 kPa, the paper's 4 G_e against
    5 G_e), a reduced ladder (0.78 mm, the two fastest speeds), ``gelrig analyze
    --anisotropic``: the intervals of G_1_h and G_1_v are apart, and the summary says mu from
    F_h/F_v is biased; the isotropic twin's same ladder does not."""
    proto = paper_ladder.protocol(overlaps=1, speeds=["1.19e-4 m/s", "2.37e-4 m/s"])
    run = paper_ladder.record(tmp_path / "run", paper_ladder.rig(
        link="direct", relax_vertical=[["16000 Pa", "2000 s"]]), proto)
    printed = analyze(capsys, run, tmp_path / "out", "--anisotropic")
    assert any(ANISOTROPIC in w for w in warnings(printed)), printed
    same = paper_ladder.record(tmp_path / "iso", paper_ladder.rig(link="direct"), proto)
    printed = analyze(capsys, same, tmp_path / "out_iso", "--anisotropic")
    assert not any(ANISOTROPIC in w for w in warnings(printed)), printed
