"""Speed of the batched sine fit against a streaming read and against peers.

Run: ``python benchmarks/bench_sinefit.py [--channels 64] [--log2n 20]``.
Prints, in one run on the same array, the time of a plain streaming read
(``np.sum``), the batched fit, ``np.linalg.lstsq`` per channel and
``scipy.optimize.curve_fit`` on a subset, and their ratios.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import curve_fit

from senscal import fit_sine


def best_of(fn, repeat=3):
    best = math.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--channels", type=int, default=64)
    ap.add_argument("--log2n", type=int, default=20)
    ap.add_argument("--subset", type=int, default=4, help="channels timed with lstsq / curve_fit")
    args = ap.parse_args()
    c, n = args.channels, 2**args.log2n
    fs, f = 10_000.0, 123.4
    rng = np.random.default_rng(0)
    t = np.arange(n) / fs
    y = np.empty((c, n))
    for i in range(c):
        y[i] = rng.uniform(0.5, 2) * np.sin(2 * np.pi * f * t + rng.uniform(-3, 3)) + rng.normal(0, 0.1, n)

    fit_sine(y[:2, :4096], fs=fs, freq=f)  # compile once, outside the timing
    t_read, _ = best_of(lambda: y.sum(axis=1))
    t_fit, fit = best_of(lambda: fit_sine(y, fs=fs, freq=f))
    # The default fit also tests every channel's residual for whiteness (its
    # lag-one sum is taken in the same pass); noise_model="white" skips the switch.
    t_white, _ = best_of(lambda: fit_sine(y, fs=fs, freq=f, noise_model="white"))

    k = min(args.subset, c)

    def per_channel_lstsq():
        a = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones(n)])
        return [np.linalg.lstsq(a, y[i], rcond=None)[0] for i in range(k)]

    t_lstsq_k, _ = best_of(per_channel_lstsq, repeat=1)
    t_lstsq = t_lstsq_k / k * c

    def model(tt, a, b, d):
        return a * np.sin(2 * np.pi * f * tt) + b * np.cos(2 * np.pi * f * tt) + d

    t_cf_k, _ = best_of(lambda: [curve_fit(model, t, y[i], p0=[1, 0, 0]) for i in range(k)], repeat=1)
    t_cf = t_cf_k / k * c

    gb = y.nbytes / 1e9
    print(f"data: {c} channels x 2^{args.log2n} samples ({gb:.2f} GB float64)")
    print(f"streaming read (np.sum)          {t_read * 1e3:9.1f} ms   ({gb / t_read:.1f} GB/s)")
    print(f"batched fit_sine (known f)       {t_fit * 1e3:9.1f} ms   ratio to read: {t_fit / t_read:.2f}x"
          f"   (channels switched to coloured noise: {int(np.sum(np.asarray(fit.noise_model) == 'coloured'))})")
    print(f"  same, noise_model='white'      {t_white * 1e3:9.1f} ms   ratio to read: {t_white / t_read:.2f}x")
    print(f"np.linalg.lstsq per channel      {t_lstsq * 1e3:9.1f} ms   (from {k} channels)  speed-up of fit_sine: {t_lstsq / t_fit:.0f}x")
    print(f"scipy curve_fit per channel      {t_cf * 1e3:9.1f} ms   (from {k} channels)  speed-up of fit_sine: {t_cf / t_fit:.0f}x")
    print(f"targets: fit within 2x of read -> {'met' if t_fit <= 2 * t_read else 'NOT met'}; "
          f">= 20x faster than lstsq -> {'met' if t_lstsq >= 20 * t_fit else 'NOT met'}")
    assert np.all(np.isfinite(fit.amplitude))


if __name__ == "__main__":
    main()
