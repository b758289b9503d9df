# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/counter_out/cont_gen_dig_pulse_train.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Example for continuously generating digital pulse train.

This example demonstrates how to generate a continuous digital
pulse train from a Counter Output Channel. The Frequency, Duty
Cycle, and Idle State are all configurable.
"""

import nidaqmx
from nidaqmx.constants import AcquisitionType, Level

with nidaqmx.Task() as task:
    channel = task.co_channels.add_co_pulse_chan_freq(
        "Dev1/ctr0", idle_state=Level.LOW, initial_delay=0.0, freq=1.0, duty_cycle=0.5
    )
    channel.co_pulse_term = "/Dev1/PFI12"
    task.timing.cfg_implicit_timing(sample_mode=AcquisitionType.CONTINUOUS)
    task.start()

    input("Generating pulse train. Press Enter to stop.\n")

    task.stop()
