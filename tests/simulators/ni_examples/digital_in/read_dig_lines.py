# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/digital_in/read_dig_lines.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example for reading digital signals.

This example demonstrates how to read values from one or more
digital input channels.
"""

import nidaqmx
from nidaqmx.constants import LineGrouping


with nidaqmx.Task() as task:
    task.di_channels.add_di_chan("Dev1/port0/line0:3", line_grouping=LineGrouping.CHAN_PER_LINE)

    data = task.read()
    print(f"Acquired data: {data}")
