"""Rig files the tests share: the built-in simulated compression rig with lines added."""

from __future__ import annotations

from pathlib import Path

from gelrig.protocols.rigfile import default_rig

#: The line of the built-in compression rig's [limits] table the added lines follow.
ANCHOR = 'fast_speed = "1 mm/s"'


def compression_rig_with(folder: Path, *lines: str) -> Path:
    """The built-in compression rig with ``lines`` (TOML, e.g. ``'watchdog = "2 s"'``) added
    to its [limits] table, written to ``folder/rig.toml``."""
    text = default_rig("compression").read_text()
    assert ANCHOR in text, "the built-in compression rig no longer sets fast_speed"
    path = folder / "rig.toml"
    path.write_text(text.replace(ANCHOR, "\n".join((ANCHOR, *lines))))
    return path
