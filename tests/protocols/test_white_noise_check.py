"""The live fit checks its white-noise assumption against the noise measured at bring-up
(issue 30): a rig noisier than at its bring-up says so in the run log; one as measured does
not."""

from __future__ import annotations

import pytest

from gelrig.instrument.analysis.live_fit import WHITE_NOISE_RATIO, white_noise_check
from gelrig.instrument.core.clock import VirtualClock
from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.store import RunDirectory
from gelrig.protocols.events import RunState
from gelrig.protocols.rigfile import default_rig, load_rig
from gelrig.protocols.spec import parse_protocol
from gelrig.terminal import record_run

STEPS = [{"kind": "compression_contact_search", "name": "contact search", "probe": "0.5 mm",
          "speed": "0.3 mm/s", "threshold": "5 mN", "retract": "0.5 mm", "confirm": 2,
          "rate": "100 Hz"},
         {"kind": "ramp_hold", "diameter": "18.63 mm", "name": "ramp and hold", "hold": "60 s",
          "rate": "100 Hz", "terms": 1}]


def _log_of_run(tmp_path, measured: str, real: str, chain: str = "",
                steps: list[dict] = STEPS) -> str:
    text = default_rig("compression").read_text()
    text = text.replace('noise = "0.2 mN"', f'noise = "{real}"')
    text = text.replace('gain = 1000', f'gain = 1000\nnoise = "{measured}"{chain}')
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    spec = load_rig(rig)
    assert spec.force.chain.noise == pytest.approx(float(measured.split()[0]) * 1e-3)
    protocol = parse_protocol({"protocol": {"name": "hold", "rig": "compression"},
                               "step": steps})
    run = RunDirectory.create(tmp_path / "run", {"protocol": protocol.table,
                                                 "rig": spec.table})
    state, _ = record_run(protocol, spec, VirtualClock(), run, show=False)
    assert state is RunState.COMPLETED
    return (run.path / "gelrig.log").read_text()


def test_a_rig_noisier_than_at_bring_up_is_noted(tmp_path):
    log = _log_of_run(tmp_path, measured="0.1 mN", real="0.35 mN")
    assert "the rig's white noise measured at bring-up" in log


def test_a_rig_as_measured_passes_the_check(tmp_path):
    log = _log_of_run(tmp_path, measured="0.35 mN", real="0.35 mN")
    assert "white noise measured at bring-up" not in log


def test_a_rig_whose_confirmed_noise_is_correlated_beyond_its_white_level_is_noted(tmp_path):
    """Bring-up found a correlated part beside the white noise: the twin learns it from the
    confirmed [force.chain], and the live fit, which assumes white noise, says it does not
    hold (its intervals would be too narrow)."""
    # the contact search's threshold well above the slow part (at 5 mN its first-touch fit
    # fails on this rig, as it does on 0.86 mN of white noise)
    steps = [{**STEPS[0], "threshold": "10 mN"}, STEPS[1]]
    log = _log_of_run(tmp_path, measured="0.35 mN", real="0.35 mN", steps=steps,
                      chain='\nnoise_correlated = "0.6 mN"\nnoise_tau = "2 s"')
    assert "the rig's white noise measured at bring-up" in log


def test_a_correlated_part_without_its_time_is_one_line(tmp_path):
    text = default_rig("compression").read_text().replace(
        "gain = 1000", 'gain = 1000\nnoise_correlated = "0.7 mN"')
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_rig(rig)
    message = str(err.value)
    assert "\n" not in message and "noise_correlated" in message and "noise_tau" in message


def test_the_check_itself():
    assert white_noise_check(1.0, 1.0) is None
    assert white_noise_check(WHITE_NOISE_RATIO * 1.01, 1.0) is not None
    assert white_noise_check(5.0, float("nan")) is None


def test_the_confirmed_correlated_part_widens_the_live_fits_errors(tmp_path):
    """The hold's live fit takes the factor of the confirmed correlated part (issue 30):
    its errors, forecasts and hence an adaptive hold's end allow for it."""
    from gelrig.instrument.analysis.live_fit import correlated_inflation
    from gelrig.protocols.steps.ramp_hold import RampHoldParams, _inflation

    text = default_rig("compression").read_text().replace(
        "gain = 1000", 'gain = 1000\nnoise = "0.35 mN"\nnoise_correlated = "0.6 mN"\n'
                       'noise_tau = "2 s"')
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    chain = load_rig(rig).force.chain
    params = RampHoldParams(diameter=18.63e-3, hold=600.0, rate=100.0)
    factor = _inflation(chain, params)
    assert factor == pytest.approx(correlated_inflation(0.35e-3, 0.6e-3, 2.0, 100.0, 600.0))
    assert factor > 15  # 2 s of correlation at 100 Hz: about 400 samples count as one
    white = load_rig(default_rig("compression")).force.chain
    assert _inflation(white, params) == 1.0
