# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/digital_in/read_dig_port.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example for reading a digital signal.

This example demonstrates how to read values from a digital
input port.
"""

import nidaqmx
from nidaqmx.constants import LineGrouping


with nidaqmx.Task() as task:
    task.di_channels.add_di_chan("Dev1/port0", line_grouping=LineGrouping.CHAN_FOR_ALL_LINES)

    data = task.read()
    print(f"Acquired data: {data:#x}")
