# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/digital_out/write_dig_lines.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example for generating digital signals.

This example demonstrates how to write values to a digital
output channel.
"""

import nidaqmx
from nidaqmx.constants import LineGrouping

with nidaqmx.Task() as task:
    data = [True, False, True, False]

    task.do_channels.add_do_chan("Dev1/port0/line0:3", line_grouping=LineGrouping.CHAN_PER_LINE)
    task.start()
    task.write(data)
    task.stop()
