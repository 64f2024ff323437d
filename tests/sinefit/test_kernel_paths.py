"""The NumPy path (small records) and the compiled path (large ones) of the fast sine fit agree to rounding."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.sinefit import _kernels as k


@pytest.mark.parametrize("nch, n, harmonics, drift", [(1, 257, 1, False), (4, 2000, 1, True), (3, 5003, 3, True)])
def test_numpy_and_compiled_sums_agree(nch, n, harmonics, drift):
    rng = np.random.default_rng(n)
    y = rng.normal(size=(nch, n)) + 3.0
    pilot = y[:, 0].copy()
    w_dt, tau0_w = 0.0137, -2.9
    c = k.compiled()
    tau = np.arange(n) * 1e-3 - 0.5
    pairs = [
        (k.gram_rotated(n, w_dt, tau0_w), c.gram_rotated(n, w_dt, tau0_w)),
        (k.harmonic_basis(n, w_dt, tau0_w, harmonics), c.harmonic_basis_serial(n, w_dt, tau0_w, harmonics)),
        *zip(k.project_rotated_serial(y, w_dt, tau0_w, pilot), c.project_rotated_serial(y, w_dt, tau0_w, pilot)),
    ]
    basis = c.harmonic_basis_serial(n, w_dt, tau0_w, harmonics)
    pairs += list(zip(k.project_serial(y, basis, tau, drift, pilot, 1), c.project_serial(y, basis, tau, drift, pilot, 1)))
    coef = rng.normal(size=(nch, 2 * harmonics + 1 + int(drift)))
    rows = np.arange(nch)
    pairs += list(zip(k.residual_ss(y, basis, tau, drift, coef, rows), c.residual_ss(y, basis, tau, drift, coef, rows)))
    assert y.size < k.COMPILED_MIN_SAMPLES  # the public functions took the NumPy path
    for a, b in pairs:
        scale = np.maximum(np.abs(b), np.max(np.abs(b)))
        assert np.all(np.abs(a - b) <= 1e-12 * scale)


def test_small_records_do_not_compile(monkeypatch):
    # A small fit must never reach numba (its compilation is what a first run waits for).
    from senscal import fit_sine

    def refuse():
        raise AssertionError("the compiled kernels were asked for on a small record")

    monkeypatch.setattr(k, "compiled", refuse)
    t = np.arange(2000) / 1000.0
    y = np.sin(2 * np.pi * 12.5 * t) + np.random.default_rng(0).normal(0, 0.01, (3, t.size))
    fit_sine(y, t, freq=12.5)
    fit_sine(y[0], t)
    fit_sine(y, t, freq=12.5, harmonics=2, drift=True)
