"""The step kinds a protocol file or a script can name: the built-in ones, each in its own
module, and those a user module registers (:func:`register`, :func:`load_step_modules`)."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TypeVar

from gelrig.instrument.core.errors import ConfigError
from gelrig.protocols.steps.base import StepDefinition, StepParams, StepResult
from gelrig.protocols.steps.compression_search import CompressionContactSearch
from gelrig.protocols.steps.creep import Creep
from gelrig.protocols.steps.ladder import SpeedLadder
from gelrig.protocols.steps.load_unload import LoadUnload
from gelrig.protocols.steps.move import Move
from gelrig.protocols.steps.ramp_hold import RampHold
from gelrig.protocols.steps.rest import Rest
from gelrig.protocols.steps.shear_search import ShearContactSearch
from gelrig.protocols.steps.shear_wait import ShearWait
from gelrig.protocols.steps.wait import Wait

#: kind -> definition, for protocol files and scripts
KINDS: dict[str, StepDefinition[Any, Any, Any]] = {
    d.kind: d
    for d in (CompressionContactSearch(), RampHold(), Wait(), Move(), Rest(), LoadUnload(),
              Creep(), ShearContactSearch(), ShearWait(), SpeedLadder())
}
#: the kinds gelrig ships: no user module may replace them
BUILT_IN = frozenset(KINDS)

D = TypeVar("D", bound=type[StepDefinition[Any, Any, Any]])


def register(definition: D) -> D:
    """Class decorator: make a step kind nameable from protocol files and scripts by its
    ``kind``. A kind is registered once; the same class loaded again (a module imported both
    by a script and by a protocol file's ``step_kinds``) replaces itself."""
    kind = getattr(definition, "kind", "")
    if not isinstance(kind, str) or not kind.isidentifier():
        raise ConfigError(f"{definition.__qualname__}.kind", kind,
                          "a name of letters, digits and _ (what protocol files write)")
    for attr in ("rig", "Params", "Result"):
        if not hasattr(definition, attr):
            raise ConfigError(f"{definition.__qualname__}.{attr}", "missing",
                              "a step kind names its rig class, Params and Result")
    known = KINDS.get(kind)
    if known is not None:
        if kind in BUILT_IN:
            raise ConfigError(f"{definition.__qualname__}.kind", kind,
                              "is a built-in step kind; choose another name")
        if _origin(type(known)) != _origin(definition):
            raise ConfigError(f"{definition.__qualname__}.kind", kind,
                              f"is already registered by {_origin(type(known))}")
    KINDS[kind] = definition()
    return definition


def _origin(cls: type) -> str:
    module = sys.modules.get(cls.__module__)
    where = getattr(module, "__file__", None) or cls.__module__
    return f"{cls.__qualname__} in {Path(where).resolve() if where else cls.__module__}"


def load_step_modules(names: Sequence[object], base: Path, source: str) -> None:
    """Import the modules a protocol file's ``step_kinds`` names, so that their
    :func:`register` calls run: a ``.py`` path relative to the protocol file (``base``: its
    folder), or a dotted module name of an installed package. Importing runs the module's
    code, like ``gelrig run script.py`` does."""
    for i, name in enumerate(names):
        key = f"[protocol] step_kinds[{i}]"
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(key, name, "a .py file next to the protocol file, or a "
                              "module name", source)
        if name.endswith(".py"):
            import_file((base / name).resolve(), key, source)
            continue
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise ConfigError(key, name, f"cannot be imported ({exc})", source) from None


def import_file(path: Path, key: str = "script", source: str | None = None) -> Any:
    """Import a Python file as a module (once per file: a second call returns the same
    module); its folder goes on ``sys.path`` so that it can import its neighbours."""
    if not path.is_file():
        raise ConfigError(key, str(path), "no such Python file", source)
    name = f"gelrig_user_{path.stem}_{hashlib.sha1(str(path).encode()).hexdigest()[:8]}"
    if name in sys.modules:
        return sys.modules[name]
    folder = str(path.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ConfigError(key, str(path), "cannot be imported as Python", source)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except ConfigError:
        del sys.modules[name]
        raise
    except SyntaxError as exc:
        del sys.modules[name]
        raise ConfigError(key, f"{path.name}:{exc.lineno}", f"is not valid Python "
                          f"({exc.msg})", source) from None
    except Exception as exc:  # the user's module failed at import: where, in one line
        del sys.modules[name]
        line = next((f.lineno for f in reversed(traceback.extract_tb(exc.__traceback__))
                     if Path(f.filename).resolve() == path), None)
        raise ConfigError(key, f"{path.name}:{line}" if line else path.name,
                          f"raised {type(exc).__name__}: {exc} while loading", source) from None
    except BaseException:
        del sys.modules[name]
        raise
    return module


__all__ = ["BUILT_IN", "KINDS", "StepDefinition", "StepParams", "StepResult", "import_file",
           "load_step_modules", "register"]
