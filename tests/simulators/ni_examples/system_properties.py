# Vendored unmodified from https://github.com/ni/nidaqmx-python, examples/system_properties.py
# (commit cbba502321e6a51fe9b10e9c907c9032833e9e5e). Copyright (c) 2022, National
# Instruments Corp.; MIT licence, see LICENSE in this folder. Only these lines are added.
"""Examples for using system properties in DAQmx."""

import nidaqmx.system

local_system = nidaqmx.system.System.local()
driver_version = local_system.driver_version

print(
    "DAQmx {}.{}.{}".format(
        driver_version.major_version,
        driver_version.minor_version,
        driver_version.update_version,
    )
)

for device in local_system.devices:
    print(
        "Device Name: {}, Product Category: {}, Product Type: {}".format(
            device.name, device.product_category, device.product_type
        )
    )
