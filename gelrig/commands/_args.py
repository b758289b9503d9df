"""argparse value types for SI quantities given as numbers or unit-bearing strings.

Light to import (the parser is built on every ``gelrig`` call): the contact model is imported
only when a relaxation term is parsed.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

from gelrig.instrument.core.errors import ConfigError
from gelrig.instrument.core.units import to_si

if TYPE_CHECKING:
    from gelrig.instrument.physics.contact import RelaxationTerm


def quantity(unit: str, minimum: float | None = 0.0, strict: bool = True) -> Callable[[str], float]:
    """A type that parses '1.5', '1.5 mm' ... to SI ``unit`` and checks the lower bound."""

    def parse(text: str) -> float:
        try:
            value = to_si(text, unit, "value")
        except ConfigError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: {exc.allowed}") from None
        if minimum is not None and (value <= minimum if strict else value < minimum):
            sign = ">" if strict else ">="
            raise argparse.ArgumentTypeError(f"{text!r}: must be {sign} {minimum:g} {unit}")
        return value

    parse.__name__ = f"quantity in {unit}"
    return parse


def poisson(text: str) -> float:
    """Poisson ratio, 0 <= nu < 1."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number 0 <= nu < 1") from None
    if not 0 <= value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: Poisson ratio must satisfy 0 <= nu < 1")
    return value


def relax_term(text: str) -> RelaxationTerm:
    """'G:TAU' with G in Pa and TAU in s, e.g. '2e4:2000' or '20 kPa:2000 s'."""
    from gelrig.instrument.physics.contact import RelaxationTerm

    parts = text.split(":")
    if len(parts) != 2 or not all(p.strip() for p in parts):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected G:TAU, e.g. 2e4:2000 or '20 kPa:2000 s'"
        )
    try:
        g = to_si(parts[0], "Pa", "G")
        tau = to_si(parts[1], "s", "tau")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: {exc.field} {exc.allowed}") from None
    if g < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: G must be >= 0 Pa")
    if tau <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: TAU must be > 0 s")
    return RelaxationTerm(g, tau)


def add_material(parser: argparse.ArgumentParser) -> None:
    """--g-e, --relax (repeatable), --nu."""
    parser.add_argument("--g-e", required=True, type=quantity("Pa"), metavar="GE",
                        help="equilibrium shear modulus G_e (Pa, or e.g. '4 kPa')")
    parser.add_argument("--relax", action="append", default=[], type=relax_term,
                        metavar="G:TAU", help="a relaxation term G (Pa) : tau (s); repeatable")
    parser.add_argument("--nu", type=poisson, default=0.5, help="Poisson ratio (default 0.5)")
