"""NI's own nidaqmx examples, unmodified, against the served simulated USB-6001.

Code gelrig did not write: ``tests/simulators/ni_examples`` (vendored, MIT). An example a
USB-6001 can run must end normally with what it prints; one that needs hardware the 6001
lacks must end with the DAQmx code NI-DAQmx gives for that (docs/decisions/0290; which code a
real 6001 gives is UNVERIFIED where that record says so). The README's table lists the same.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.simulators.ni_runner import EXAMPLES, run_example

#: example -> text its output must contain (it runs on a 6001)
RUNS = {
    "analog_in/voltage_sample.py": "Acquired data: ",
    "analog_in/voltage_acq_int_clk.py": "Acquired data: [",
    "analog_in/voltage_acq_int_clk_wfm.py": "dt: 0:00:00.001000",
    "analog_in/voltage_acq_int_clk_tdms_logging.py": "Read data from TDMS file: [",
    "analog_in/cont_voltage_acq_int_clk.py": "total samples.",
    "analog_in/cont_voltage_acq_int_clk_every_n_samples_event.py": "Acquired 2000 total samples",
    "analog_in/cont_voltage_acq_int_clk_dig_start.py": "Acquired 1000 total samples",
    "analog_out/voltage_update.py": "Generated 1 voltage sample.",
    "analog_out/gen_voltage_wfm_int_clk.py": "Generating 1000 voltage samples.",
    "analog_out/cont_gen_voltage_wfm_int_clk.py": "Actual sampling rate: 1000 S/s",
    "analog_out/cont_gen_voltage_wfm_int_clk_non_regen.py": "Press Ctrl+C to stop.",
    "analog_out/cont_gen_voltage_wfm_int_clk_every_n_samples_event.py":
        "Transferred 2000 total samples.",
    "digital_in/read_dig_lines.py": "Acquired data: [True, True, True, True]",
    "digital_in/read_dig_port.py": "Acquired data: 0xff",
    "digital_out/write_dig_lines.py": "",
    "digital_out/write_dig_port.py": "",
    "channel_properties.py": "0.1\n-0.1\n5.0\n-0.1\n10.0\n-10.0\n5.0\n-0.1\nDev1/ai2\n",
    "system_properties.py": "Product Type: USB-6001",
    "every_n_samples_event.py": "Every N Samples callback invoked.",
    "nidaqmx_warnings.py": "",
    "synchronization/multi_function/ai_ao_sync.py": "Acquired 2000 total samples.",
}

#: example -> the DAQmx code it must end with on a USB-6001 (what the device lacks)
REFUSED = {
    "analog_in/thrmcpl_sample.py": -200431,  # no thermocouple input
    "analog_in/cont_thrmcpl_samples_int_clk.py": -200431,
    "analog_in/calculated_power_acq_int_clk.py": -200431,
    "analog_in/cont_calculated_power_acq_int_clk.py": -200431,
    "pwr_sw_timed.py": -200431,  # no power channels
    "pwr_hw_timed.py": -200431,
    "pwr_hw_timed_stream.py": -200431,
    "analog_in/voltage_acq_int_clk_dig_ref.py": -200077,  # no reference trigger
    "analog_in/voltage_acq_int_clk_dig_start_ref.py": -200077,
    "analog_in/cont_voltage_acq_int_clk_dig_start_retrig.py": -200452,  # no retriggering
    "counter_in/read_freq.py": -200431,  # ctr0 counts edges only
    "counter_in/read_pulse_freq.py": -200431,
    "counter_in/cont_read_buff_freq.py": -200431,
    "counter_in/cnt_dig_event.py": -89120,  # it counts on /Dev1/PFI8; a 6001 has PFI0 only
    "counter_in/cont_cnt_buff_event_ext_clk.py": -200077,  # no buffered counting, no PFI9
    "counter_out/write_single_dig_pulse.py": -200430,  # no counter output
    "counter_out/cont_gen_dig_pulse_train.py": -200430,
    "counter_out/cont_gen_dig_pulse_train_buff_ext_clk.py": -200430,
    "counter_out/cont_gen_dig_pulse_train_buff_implicit.py": -200430,
    "digital_in/acq_dig_port_int_clk.py": -200077,  # static DIO: on demand only
    "digital_in/cont_acq_dig_lines_int_clk.py": -200077,
    "digital_out/gen_dig_line_int_clk.py": -200077,
    "digital_out/cont_gen_dig_port_int_clk.py": -200077,
    "digital_out/cont_gen_dig_port_int_clk_wfm.py": -200077,
    "synchronization/multi_function/cont_ai_di_acq.py": -200077,
    "synchronization/multi_function/cont_ai_ci_tdms_sync.py": -200077,
}

#: examples that loop until Ctrl+C without waiting for Enter: interrupted at their 21st call
LOOPS = {"analog_out/cont_gen_voltage_wfm_int_clk_non_regen.py": 20,
         "analog_in/cont_voltage_acq_int_clk.py": 20}


def test_every_vendored_example_is_run() -> None:
    vendored = {str(p.relative_to(EXAMPLES)) for p in EXAMPLES.rglob("*.py")}
    assert vendored == set(RUNS) | set(REFUSED)


@pytest.mark.parametrize("example", sorted(RUNS))
def test_an_example_a_6001_runs_runs(example: str, tmp_path: Path) -> None:
    outcome = run_example(example, tmp_path, limit=LOOPS.get(example))
    assert outcome.code is None, outcome.error
    assert RUNS[example] in outcome.output


@pytest.mark.parametrize("example", sorted(REFUSED))
def test_an_example_needing_what_a_6001_lacks_ends_in_nis_code(example: str,
                                                               tmp_path: Path) -> None:
    outcome = run_example(example, tmp_path, limit=20)  # should it get as far as a loop
    assert outcome.code == REFUSED[example], outcome.error


def test_the_digital_examples_drive_the_twins_lines(tmp_path: Path) -> None:
    lines = run_example("digital_out/write_dig_lines.py", tmp_path).lines
    assert lines[:4] == (True, False, True, False)  # it writes [True, False, True, False]
    assert all(run_example("digital_out/write_dig_port.py", tmp_path).lines[:8])  # 0xFFFFFFFF


def test_the_ao_examples_leave_the_dac_where_they_wrote_it(tmp_path: Path) -> None:
    update = run_example("analog_out/voltage_update.py", tmp_path)
    assert update.ao[0] == pytest.approx(1.1, abs=2e-3)
    ramp = run_example("analog_out/gen_voltage_wfm_int_clk.py", tmp_path)
    assert ramp.ao[0] == pytest.approx(5.0 * 999 / 1000, abs=2e-3)  # its last sample, held
