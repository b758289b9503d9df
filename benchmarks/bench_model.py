"""Contact-model throughput on a 3000 s hold at 1 kHz (3e6 samples).

Run: python benchmarks/bench_model.py [--repeats 7]

Prints samples/s (median of the repeats) for the batch and streaming paths with 1 and 2
relaxation terms, each with its ratio to plain numpy passes over an array of the same length
measured in the same run (an elementwise multiply, and a cumulative sum: the simplest
sequential scan), and the naive O(N^2) double sum on 1e4 samples for contrast. A third
baseline, ``x ** 1.5``, is the model's own nonlinearity as one numpy ufunc pass.
"""

from __future__ import annotations

import argparse

import numpy as np
from _timing import median_time

from gelrig.instrument.physics import paper
from gelrig.instrument.physics.compression import ramp_hold_overlap
from gelrig.instrument.physics.contact import (
    Material,
    NormalContact,
    hertz_prefactor,
    normal_force_uniform,
)

N = 3_000_000
DT = 1e-3


def naive(t: np.ndarray, x: np.ndarray, material: Material, radius: float) -> np.ndarray:
    """The O(N^2) hereditary sum, vectorised per output sample (the thing never to ship)."""
    k = hertz_prefactor(radius, material.nu)
    dx = np.diff(x, prepend=0.0)
    out = np.empty(t.size)
    for n in range(t.size):
        hat = sum(term.g * np.sum(np.exp(-(t[n] - t[: n + 1]) / term.tau) * dx[: n + 1])
                  for term in material.relax)
        out[n] = max(0.0, k * (material.g_e * x[n] + hat))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    repeats = parser.parse_args().repeats
    t = np.arange(N) * DT
    delta = ramp_hold_overlap(t, paper.DEPTH_HOLD, paper.RAMP_SPEED)
    a = np.random.default_rng(0).random(N)
    base_mul = median_time(lambda: np.multiply(a, 1.5), repeats)
    base_scan = median_time(lambda: np.cumsum(a), repeats)
    base_pow = median_time(lambda: np.power(a, 1.5), repeats)
    print(f"3000 s hold at 1 kHz: {N:.0e} samples; median of {repeats} runs")
    print(f"baseline numpy multiply pass: {N / base_mul / 1e6:8.1f} M samples/s")
    print(f"baseline numpy cumsum pass:   {N / base_scan / 1e6:8.1f} M samples/s")
    print(f"baseline numpy x**1.5 pass:   {N / base_pow / 1e6:8.1f} M samples/s")
    header = (f"{'path':34s} {'M samples/s':>11s} {'x multiply':>10s} {'x x**1.5':>9s} "
              f"{'x cumsum':>9s}")
    print(header)
    print("-" * len(header))
    materials = {"1 term": paper.PLATES, "2 terms": paper.SHELL}
    r = paper.R_COMPRESSION
    for label, material in materials.items():
        runs = {
            f"batch, {label}": (lambda m=material: normal_force_uniform(delta, DT, m, r), N),
            f"streaming 100-sample blocks, {label}": (
                lambda m=material: _stream_blocks(delta, m, r, 100), N),
            f"streaming per sample, {label}": (
                lambda m=material: _stream_steps(t[:200_000], delta[:200_000], m, r), 200_000),
        }
        for name, (fn, count) in runs.items():
            reps = repeats if count == N or "per sample" not in name else max(3, repeats // 2)
            elapsed = median_time(fn, reps) * N / count
            print(f"{name:34s} {N / elapsed / 1e6:11.1f} {elapsed / base_mul:10.1f} "
                  f"{elapsed / base_pow:9.1f} {elapsed / base_scan:9.1f}")
    n_naive = 10_000
    tn, xn = t[:n_naive], np.maximum(delta[:n_naive], 0.0) ** 1.5
    naive_time = median_time(lambda: naive(tn, xn, paper.PLATES, r), 1)
    fast_time = median_time(lambda: normal_force_uniform(delta[:n_naive], DT, paper.PLATES, r), 5)
    print(f"naive O(N^2) on {n_naive:.0e} samples: {naive_time:.2f} s "
          f"({n_naive / naive_time / 1e6:.3f} M samples/s); the recursion takes "
          f"{fast_time * 1e3:.2f} ms, {naive_time / fast_time:.0f}x faster; at 3e6 samples the "
          f"naive sum would take ~{naive_time * (N / n_naive) ** 2 / 3600:.0f} h")


def _stream_blocks(delta: np.ndarray, material: Material, radius: float, block: int) -> None:
    contact = NormalContact(material, radius)
    for i in range(0, delta.size, block):
        contact.block_uniform(delta[i : i + block], DT)


def _stream_steps(t: np.ndarray, delta: np.ndarray, material: Material, radius: float) -> None:
    contact = NormalContact(material, radius)
    for ti, di in zip(t.tolist(), delta.tolist(), strict=True):
        contact.step(ti, di)


if __name__ == "__main__":
    main()
