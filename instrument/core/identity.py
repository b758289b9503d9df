"""Who answered: one identity record for every instrument, as run.json stores it."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Identity:
    """An instrument's identity as read from it when it was opened.

    ``vendor`` and ``model`` say what it is, ``serial``, ``firmware`` and ``hardware`` which
    one (empty when the instrument does not report it). ``extra`` holds instrument-specific
    facts (a DAQ channel, an axis count) and the key names run.json used before ADR 0050,
    so readers of older runs find the same keys in newer ones.
    """

    vendor: str
    model: str
    serial: str
    firmware: str = ""
    hardware: str = ""
    extra: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        clash = sorted(set(self.extra) & _FIELDS)
        if clash:
            raise ValueError(f"Identity.extra may not redefine {', '.join(clash)}")

    def as_dict(self) -> dict[str, str]:
        """A flat mapping for run.json: the fields, then ``extra``."""
        return {"vendor": self.vendor, "model": self.model, "serial": self.serial,
                "firmware": self.firmware, "hardware": self.hardware, **self.extra}

    def __str__(self) -> str:
        firmware = f" firmware {self.firmware}" if self.firmware else ""
        return f"{self.vendor} {self.model} serial {self.serial}{firmware}"


_FIELDS = frozenset({"vendor", "model", "serial", "firmware", "hardware"})
