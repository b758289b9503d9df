# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/counter_in/read_freq.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example of counter input frequency acquisition.

This example demonstrates how to measure frequency using one
counter on a Counter Input Channel. The Edge, Minimum Value and
Maximum Value are all configurable.
"""

import nidaqmx
from nidaqmx.constants import Edge, FrequencyUnits


with nidaqmx.Task() as task:
    channel = task.ci_channels.add_ci_freq_chan(
        "Dev1/ctr0",
        min_val=2.0,
        max_val=100000.0,
        units=FrequencyUnits.HZ,
        edge=Edge.RISING,
    )
    channel.ci_freq_term = "/Dev1/PFI8"

    task.start()

    data = task.read()
    print(f"Acquired frequency: {data:.2f} Hz")

    task.stop()
