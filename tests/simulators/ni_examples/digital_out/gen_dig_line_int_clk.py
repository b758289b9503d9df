# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/digital_out/gen_dig_line_int_clk.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example for generating digital signals.

This example demonstrates how to output a finite digital
waveform using the DAQ device's internal clock.
"""

import nidaqmx
from nidaqmx.constants import AcquisitionType, LineGrouping

with nidaqmx.Task() as task:
    data = [bool(i % 2) for i in range(1000)]

    task.do_channels.add_do_chan("Dev1/port0/line0", line_grouping=LineGrouping.CHAN_PER_LINE)
    task.timing.cfg_samp_clk_timing(
        1000.0, sample_mode=AcquisitionType.FINITE, samps_per_chan=len(data)
    )

    number_of_samples_written = task.write(data)
    task.start()
    print(f"Generating {number_of_samples_written} voltage samples.")
    task.wait_until_done()
    task.stop()
