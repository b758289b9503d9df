"""``gelrig model compression|shear``: the contact model written to CSV."""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import TYPE_CHECKING

from gelrig.commands._args import add_material, quantity, relax_term
from gelrig.instrument.core.errors import ConfigError

if TYPE_CHECKING:  # the model is imported when the command runs
    from gelrig.instrument.physics.contact import FloatArray, Material


def register(sub: argparse._SubParsersAction) -> None:
    model = sub.add_parser("model", help="compute the contact model and write CSV")
    which = model.add_subparsers(dest="model", metavar="EXPERIMENT")
    which.required = True

    comp = which.add_parser("compression", help="plate ramp from first touch, then a hold")
    comp.add_argument("--radius", required=True, type=quantity("m"), help="sphere radius (m)")
    comp.add_argument("--depth", required=True, type=quantity("m"), help="hold overlap (m)")
    comp.add_argument("--rate", required=True, type=_rate, metavar="V",
                      help="plate speed (m/s, or '37 um/s'); a strain rate like '0.002/s' "
                           "is taken relative to the diameter")
    comp.add_argument("--hold", required=True, type=quantity("s", strict=False),
                      help="hold duration (s)")
    add_material(comp)
    comp.add_argument("--dt", type=quantity("s"), default=0.01, help="sample step (s, 0.01)")
    add_unloading(comp)
    comp.add_argument("--out", required=True, help="CSV file: t_s,delta_m,force_N")
    comp.set_defaults(handler=run_compression)

    shear = which.add_parser("shear", help="one pass of the upper sphere over the lower one")
    shear.add_argument("--r1", required=True, type=quantity("m"), help="upper sphere radius (m)")
    shear.add_argument("--r2", required=True, type=quantity("m"), help="lower sphere radius (m)")
    shear.add_argument("--delta-max", required=True, type=quantity("m"), metavar="DM",
                       help="maximum overlap (m)")
    shear.add_argument("--speed", required=True, type=quantity("m/s"),
                       help="linear sliding speed at the arm (m/s)")
    add_material(shear)
    shear.add_argument("--mu", type=quantity("", strict=False), default=0.0,
                       help="Coulomb friction coefficient (default 0)")
    shear.add_argument("--dt", type=quantity("s"), default=None,
                       help="sample step (s; default: travel / 2000 samples)")
    shear.add_argument("--margin", type=quantity("m", strict=False), default=0.0,
                       help="travel before first touch and after psi0 on the far side (m)")
    shear.add_argument("--relax-vertical", action="append", default=[], type=relax_term,
                       metavar="G:TAU", help="relaxation term of the modulus F_v is computed "
                       "with (the paper's anisotropy, e.g. 16e3:2000); repeatable; default: "
                       "--relax")
    add_unloading(shear)
    shear.add_argument("--out", required=True, help="CSV: t_s,psi_m,delta_m,f_perp_N,f_h_N,f_v_N")
    shear.set_defaults(handler=run_shear)


UNLOADING = ("cutoff", "mdr")


def add_unloading(parser: argparse.ArgumentParser) -> None:
    """--unloading cutoff|mdr: the paper's no-adhesion cutoff, or MDR (docs/decisions/0150)."""
    parser.add_argument("--unloading", choices=UNLOADING, default="cutoff",
                        help="unloading model: cutoff (the paper's, default) or mdr "
                             "(viscoelastic MDR elements that separate and recover)")


def _mdr_force(args: argparse.Namespace, radius: float, t: FloatArray, delta: FloatArray,
               ) -> FloatArray:
    """F_perp of a fresh MDR contact over the same samples (used with --unloading mdr)."""
    from gelrig.instrument.physics.mdr import MdrContact

    peak = max(float(delta.max()), 1e-9)
    return MdrContact(_material(args), radius, delta_max=peak).block(t, delta)


def _rate(text: str) -> tuple[str, float]:
    """A speed in m/s, or a strain rate in 1/s (resolved once the radius is known)."""
    try:
        return "speed", quantity("m/s")(text)
    except argparse.ArgumentTypeError as speed_error:
        try:
            return "strain", quantity("1/s")(text)
        except argparse.ArgumentTypeError:
            raise speed_error from None


#: Most samples a model may compute: 8 arrays of float64 stay under ~6 GB.
MAX_SAMPLES = 100_000_000


def check_samples(duration: float, dt: float, what: str) -> None:
    """Refuse a --dt whose arrays would not fit comfortably in memory, before allocating."""
    n = duration / dt
    if not n <= MAX_SAMPLES:  # also catches inf and nan
        raise ConfigError("--dt", dt, f"gives {n:.3g} samples over the {what} "
                          f"({duration:.4g} s); at most {MAX_SAMPLES:.0e} are allowed: use "
                          f"--dt >= {duration / MAX_SAMPLES:.3g} s")


def _material(args: argparse.Namespace) -> Material:
    from gelrig.instrument.physics.contact import Material

    return Material(args.g_e, tuple(args.relax), args.nu)


def run_compression(args: argparse.Namespace) -> int:
    from gelrig.instrument.core.csvio import write_columns
    from gelrig.instrument.physics.compression import ramp_hold

    kind, value = args.rate
    speed = value if kind == "speed" else value * 2.0 * args.radius
    if args.depth >= args.radius:
        raise ConfigError("--depth", args.depth, f"must be < --radius ({args.radius:g} m)")
    check_samples(args.depth / speed + args.hold, args.dt, "ramp and hold")
    record = ramp_hold(args.radius, args.depth, speed, args.hold, _material(args), dt=args.dt)
    if args.unloading == "mdr":
        record = replace(record, force=_mdr_force(args, args.radius, record.t, record.delta))
    path = write_columns(args.out, {"t_s": record.t, "delta_m": record.delta,
                                    "force_N": record.force})
    print(f"wrote {record.t.size} samples (ramp {record.t_hold:.4g} s at {speed:.4g} m/s, "
          f"hold {args.hold:g} s; peak force {record.force.max():.4g} N) to {path}")
    return 0


def run_shear(args: argparse.Namespace) -> int:
    from gelrig.instrument.core.csvio import write_columns
    from gelrig.instrument.physics.sliding import SlidingGeometry, shear_pass

    try:
        geometry = SlidingGeometry(args.r1, args.r2, args.delta_max)
    except ConfigError as exc:
        option = f"--{exc.field.lower().replace('_', '-')}"
        raise ConfigError(option, exc.value, exc.allowed) from None
    if args.dt is not None:
        travel = 2 * (geometry.psi0 + args.margin)
        check_samples(travel / args.speed, args.dt, "pass")
    material = _material(args)
    vertical = None
    if args.relax_vertical:
        from gelrig.instrument.physics.contact import Material

        vertical = Material(args.g_e, tuple(args.relax_vertical), args.nu)
    sp = shear_pass(geometry, material, args.speed, args.mu, args.dt, args.margin,
                    material_vertical=vertical, unloading=args.unloading)
    path = write_columns(args.out, {"t_s": sp.t, "psi_m": sp.psi, "delta_m": sp.delta,
                                    "f_perp_N": sp.f_perp, "f_h_N": sp.f_h, "f_v_N": sp.f_v})
    print(f"wrote {sp.t.size} samples (l_g {geometry.l_g * 1e3:.4g} mm, peak F_h "
          f"{sp.f_h.max():.4g} N, peak F_v {sp.f_v.max():.4g} N) to {path}")
    return 0
