"""The load-cell chain (load cell -> conditioner -> ADC input) and the force-sensor contract.

Chain of the plate-compression rig (instruments.md): a bridge load cell of rated ``capacity``
and rated output (V per V of excitation), excited at ``excitation`` volts, amplified by a
conditioner of ``gain`` with an output ``offset``; the conditioner's output reaches the ADC::

    volts = offset + force * rated_output * excitation * gain / capacity

Rated output and the conditioner's gain, offset and bandwidth are UNVERIFIED for the rig
(docs/decisions/0010): they are configuration, with defaults that map the rated load to 10 V.

:class:`ForceSensor` is what the protocol runner programs against; a driver meets it (the
USB-6001 driver in drivers/usb6001) and so can any test double.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol, runtime_checkable

from gelrig.instrument.core.errors import InstrumentError, InstrumentTimeout
from gelrig.instrument.core.fields import Config, Field, Where, param
from gelrig.instrument.core.identity import Identity

if TYPE_CHECKING:  # numpy is imported when a force is converted: the configuration stays light
    from numpy.typing import ArrayLike

    from gelrig.instrument.core.arrays import BoolArray, FloatArray

#: The ``[force.chain]`` keys bring-up measures the noise into; the twin's noise unless the
#: ``[simulator]`` table sets the same key (issue 30).
NOISE_KEYS = ("noise", "noise_drift", "noise_correlated", "noise_tau")


@dataclass(frozen=True)
class LoadCellChain(Config):
    """Calibration of the force chain; SI inside (N, V, V/V, Hz).

    ``rated_output`` is the bridge output at rated load per volt of excitation (2 mV/V is
    stored as 0.002). ``bandwidth`` is the conditioner's -3 dB frequency (a simulator models it
    as one pole; a driver does not use it).
    """

    section: ClassVar[str] = "force.chain"

    capacity: float = param(Field("capacity", "N", 2.5, 0.0, 1e5, lo_open=True,
                                  help="rated load of the cell"))
    rated_output: float = param(Field("rated_output", "V/V", 2e-3, 0.0, 0.01, lo_open=True,
                                      help="bridge output at rated load per volt of excitation"))
    excitation: float = param(Field("excitation", "V", 5.0, 0.0, 15.0, lo_open=True))
    gain: float = param(Field("gain", "V/V", 1000.0, 0.0, 1e5, lo_open=True,
                              help="conditioner gain"))
    offset: float = param(Field("offset", "V", 0.0, -10.5, 10.5,
                                help="conditioner output at no load"))
    bandwidth: float = param(Field("bandwidth", "Hz", 1000.0, 0.0, 1e6, lo_open=True,
                                   help="conditioner -3 dB frequency"))
    compliance: float = param(Field("compliance", "m/N", 0.0, 0.0, 1e-2, display="um/N",
                                    help="load cell deflection per newton: the hold analysis "
                                         "subtracts it from the plate travel"))
    noise: float | None = param(Field("noise", "N", None, 0.0, 0.1, optional=True,
                                      help="the force's noise as measured at bring-up (rms, "
                                           "unloaded; issue 30): its white part"))
    # The rest of the noise measured at bring-up: a drift, and a correlated (Ornstein-
    # Uhlenbeck) part of rms ``noise_correlated`` and correlation time ``noise_tau``.
    noise_drift: float | None = param(Field("noise_drift", "N/s", None, -0.01, 0.01,
                                            optional=True, help="the unloaded force's drift "
                                            "as measured at bring-up"))
    noise_correlated: float | None = param(Field(
        "noise_correlated", "N", None, 0.0, 0.1, optional=True,
        help="rms of the noise's correlated part (exponential autocorrelation) as measured at "
             "bring-up; needs noise_tau"))
    noise_tau: float | None = param(Field("noise_tau", "s", None, 0.0, 1e4, lo_open=True,
                                          optional=True, help="correlation time of "
                                          "noise_correlated"))

    def validate(self, where: Where) -> None:
        if self.noise_correlated and self.noise_tau is None:
            raise where.error("noise_correlated", self.noise_correlated,
                              "needs noise_tau (its correlation time) beside it")

    @property
    def sensitivity(self) -> float:
        """Volts at the conditioner output per newton (V/N)."""
        return self.rated_output * self.excitation * self.gain / self.capacity

    @property
    def full_scale_volts(self) -> float:
        """Conditioner output at rated load, offset excluded (V)."""
        return self.rated_output * self.excitation * self.gain

    def volts(self, force: ArrayLike) -> FloatArray:
        """Conditioner output (V) for a force (N)."""
        import numpy as np

        return self.offset + np.asarray(force, dtype=float) * self.sensitivity

    def newtons(self, volts: ArrayLike, zero: float | None = None) -> FloatArray:
        """Force (N) for a conditioner output (V); ``zero`` (V) replaces the nominal offset.

        A tare measures ``zero`` with no load on the cell.
        """
        import numpy as np

        z = self.offset if zero is None else zero
        return (np.asarray(volts, dtype=float) - z) / self.sensitivity

@dataclass(frozen=True)
class ForceBlock:
    """One block of force samples as read: clock time (s), tared force (N), input volts (V).

    ``over_range`` marks samples beyond the input's valid range (clipped or unreliable): their
    force is a bound, not a measurement.
    """

    t: FloatArray
    force: FloatArray
    volts: FloatArray
    over_range: BoolArray

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def any_over_range(self) -> bool:
        return bool(self.over_range.any())


class AcquisitionOverflowError(InstrumentError):
    """Samples were lost: the acquisition buffer overflowed because reads fell behind."""

    def __init__(self, message: str, code: int | None = None):
        self.code = code
        super().__init__(message)


class AcquisitionTimeoutError(InstrumentTimeout):
    """The requested samples did not arrive in time; those that did are attached."""

    def __init__(self, message: str, block: ForceBlock):
        self.block = block
        super().__init__(message)


class ForceOverRangeError(InstrumentError):
    """A block holds samples beyond the input range; the block is attached, flagged."""

    def __init__(self, message: str, block: ForceBlock):
        self.block = block
        super().__init__(message)


@runtime_checkable
class ForceSensor(Protocol):
    """A hardware-timed force acquisition, as the protocol runner uses it.

    ``start`` begins continuous sampling at ``rate_hz``; ``read_block`` returns the next
    ``n`` samples (all available when ``n`` is None) with no gap or repeat between blocks and
    raises :class:`AcquisitionOverflowError` if samples were lost, and
    :class:`AcquisitionTimeoutError` or :class:`ForceOverRangeError` with the block attached
    (nothing read is dropped). ``tare`` zeroes the force on the mean of ``duration`` seconds
    of samples and returns the removed offset (N).
    """

    @property
    def rate(self) -> float:
        """Sample rate while running (Hz)."""
        ...

    def identify(self) -> Identity:
        """What is measuring: model and serial; device, channel and transport in ``extra``."""
        ...

    def start(self, rate_hz: float) -> None: ...

    def read_block(self, n: int | None = None, timeout: float | None = None) -> ForceBlock: ...

    def tare(self, duration: float = 1.0) -> float: ...

    def zero_on(self, volts: ArrayLike) -> float:
        """Zero on the mean of input volts already read (so a caller that records every sample
        can tare without losing any); returns the removed force (N)."""
        ...

    def stop(self) -> None: ...

    def close(self) -> None: ...
