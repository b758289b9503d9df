"""DAQmx error codes (names from ``nidaqmx.error_codes.DAQmxErrors``) for the USB-6001's analog
output, digital I/O, counter and triggers, with the texts the simulator answers.

The codes are NI's; the texts follow NI-DAQmx's wording as far as it could be confirmed from
NI's documents and forum reports. Which code a real USB-6001 gives for a given refusal is
marked UNVERIFIED where it was inferred (docs/decisions/0290).
"""

from __future__ import annotations

from nidaqmx.error_codes import DAQmxErrors

from gelrig.simulators.usb6001.device import ERROR_TEXT

MULTI_CHAN_TYPES_IN_TASK = DAQmxErrors.MULTI_CHAN_TYPES_IN_TASK.value  # -200559
INVALID_PHYS_CHAN_TYPE = DAQmxErrors.INVALID_PHYS_CHAN_TYPE.value  # -200430
PHYS_CHAN_MEAS_TYPE = DAQmxErrors.PHYS_CHAN_MEAS_TYPE.value  # -200431
INVALID_AO_DATA_WRITE = DAQmxErrors.INVALID_AO_DATA_WRITE.value  # -200561
GEN_STOPPED_TO_PREVENT_REGEN = DAQmxErrors.GEN_STOPPED_TO_PREVENT_REGEN_OF_OLD_SAMPLES.value
SAMPLES_CAN_NOT_YET_BE_WRITTEN = DAQmxErrors.SAMPLES_CAN_NOT_YET_BE_WRITTEN.value  # -200292
OUTPUT_BUFFER_EMPTY = DAQmxErrors.OUTPUT_BUFFER_EMPTY.value  # -200462
SAMPLES_WILL_NEVER_BE_GENERATED = DAQmxErrors.SAMPLES_WILL_NEVER_BE_GENERATED.value  # -200288
WRITE_NUM_CHANS_MISMATCH = DAQmxErrors.WRITE_NUM_CHANS_MISMATCH.value  # -200524
NUM_LINES_MISMATCH = DAQmxErrors.NUM_LINES_MISMATCH_IN_READ_OR_WRITE.value  # -200463
INVALID_ROUTING_SOURCE = DAQmxErrors.INVALID_ROUTING_SOURCE_TERMINAL_NAME_ROUTING.value  # -89120
READ_NO_INPUT_CHANS = DAQmxErrors.READ_NO_INPUT_CHANS_IN_TASK.value
WRITE_NO_OUTPUT_CHANS = DAQmxErrors.WRITE_NO_OUTPUT_CHANS_IN_TASK.value
CANNOT_WRITE_NOT_STARTED = (
    DAQmxErrors.CANNOT_WRITE_NOT_STARTED_AUTO_START_FALSE_NOT_ON_DEMAND_BUF_SIZE_ZERO.value)
LOGGING_NOT_SUPPORTED_ON_OUTPUT = DAQmxErrors.LOGGING_NOT_SUPPORT_ON_OUTPUT_TASKS.value
READ_NOT_SUPPORTED_FOR_LOGGING_MODE = DAQmxErrors.READ_NOT_SUPPORTED_FOR_LOGGING_MODE.value
LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED = (
    DAQmxErrors.LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED.value)

TEXT = {
    MULTI_CHAN_TYPES_IN_TASK: "Task cannot contain a channel of the specified type, because "
    "it contains channels of a different type. Create one task for each type of channel.",
    INVALID_PHYS_CHAN_TYPE: "I/O type of the physical channel does not match the I/O type "
    "required for the virtual channel you are creating.",
    PHYS_CHAN_MEAS_TYPE: "Measurement type not supported by the physical channel.",
    INVALID_AO_DATA_WRITE: "Attempted writing analog data that is too large or too small.",
    GEN_STOPPED_TO_PREVENT_REGEN: "The generation has stopped to prevent the regeneration of "
    "old samples. Your application was unable to write samples to the background buffer fast "
    "enough to prevent old samples from being regenerated.",
    SAMPLES_CAN_NOT_YET_BE_WRITTEN: "Some or all of the samples to write could not be written "
    "to the buffer yet. More space will free up as samples currently in the buffer are "
    "generated.",
    OUTPUT_BUFFER_EMPTY: "Generation cannot be started, because the output buffer is empty. "
    "Write data before starting a buffered generation.",
    SAMPLES_WILL_NEVER_BE_GENERATED: "Attempted to write samples that will never be "
    "generated because they are beyond the end of the finite generation.",
    WRITE_NUM_CHANS_MISMATCH: "Number of channels in the data to write does not match the "
    "number of channels in the task.",
    NUM_LINES_MISMATCH: "Number of lines in the data does not match the number of lines in "
    "the channel.",
    INVALID_ROUTING_SOURCE: "Source terminal to be routed could not be found on the device.",
    READ_NO_INPUT_CHANS: "Read cannot be performed because this task does not contain any "
    "input channels.",
    WRITE_NO_OUTPUT_CHANS: "Write cannot be performed because this task does not contain any "
    "output channels.",
    CANNOT_WRITE_NOT_STARTED: "Write cannot be performed when the auto start input to "
    "DAQmx Write is false, task is not running, timing is hardware-timed, and no buffer is "
    "configured.",
    LOGGING_NOT_SUPPORTED_ON_OUTPUT: "Logging is not supported on output tasks.",
    READ_NOT_SUPPORTED_FOR_LOGGING_MODE: "You cannot read data when the logging mode is "
    "Log: set the logging mode to Log and Read to read the data as it is logged.",
    LOGGING_MODE_NOT_SUPPORTED_NON_BUFFERED: "Logging is not supported for non-buffered "
    "(on-demand) tasks: configure a sample clock.",
}
for _code, _text in TEXT.items():
    ERROR_TEXT.setdefault(_code, _text)
