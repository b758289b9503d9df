"""Checks of a path a command will write to, without the HDF5 store (``gelrig plan`` checks
``--out`` and the free disk; importing h5py for that cost a start-up, issue 31 item 3).
:mod:`gelrig.instrument.core.store` re-exports them."""

from __future__ import annotations

import os
from pathlib import Path

from gelrig.instrument.core.errors import ConfigError


def existing_parent(path: Path) -> Path:
    """``path`` or its nearest existing parent (where its file system is)."""
    where = path.absolute()
    while where != where.parent:
        try:
            if where.exists():
                return where
        except OSError:  # a name too long to test: go up
            pass
        where = where.parent
    return where


def check_path(path: Path, option: str = "--out") -> None:
    """A path the file system can hold: every name in it within the file system's longest
    name (NAME_MAX, 255 bytes on most), the whole within its longest path."""
    base = existing_parent(path)
    try:
        name_max = os.pathconf(base, "PC_NAME_MAX")
        path_max = os.pathconf(base, "PC_PATH_MAX")
    except (OSError, ValueError, AttributeError):  # not POSIX: the common limits
        name_max, path_max = 255, 4096
    for part in path.parts:
        size = len(os.fsencode(part))
        if size > name_max:
            shown = part if len(part) <= 40 else f"{part[:37]}..."
            raise ConfigError(option, shown, f"a name of {size:,} bytes; the file system "
                              f"allows at most {name_max} bytes a name")
    size = len(os.fsencode(path.absolute()))
    if size >= path_max:
        raise ConfigError(option, f"{str(path)[:37]}...", f"a path of {size:,} bytes; the file "
                          f"system allows at most {path_max - 1}")


def check_out_dir(path: Path, option: str = "--out") -> None:
    """A folder to create a run (or a report, an export) in: new, or an empty folder."""
    check_path(path, option)
    if path.exists() and not path.is_dir():
        raise ConfigError(option, str(path), "is a file, not a folder; name a new folder")
    if (path / "run.json").exists():
        raise ConfigError(option, str(path), "already holds a run; choose a new folder "
                          "(or continue it with gelrig resume)")
    if path.is_dir() and any(path.iterdir()):
        raise ConfigError(option, str(path), "is a folder with other files in it, not a run; "
                          "name a new or empty folder")
