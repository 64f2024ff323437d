"""Does a frequency the user gave fit the data?

A three-parameter fit at a given frequency ``f0`` (``senscal fit --freq``)
reports amplitude, phase and their u as if ``f0`` were exact.  When the
signal is at another frequency ``f`` the fit still "succeeds": the phase
walks by ``2 pi (f - f0) T`` over the record and the amplitude collapses
towards the leakage of a wrong frequency (``fit --freq 10`` on a 12.5 Hz
sine of 0.1 s records gives 0.0012 for an amplitude of 1, with a U(phase)
of thousands of degrees).  Nothing in the fit's own output says why.

:func:`frequency_mismatch` compares ``f0`` with what the data say: a
four-parameter (free-frequency) fit gives ``f`` and ``u(f)``; under the
hypothesis that ``f0`` is the true frequency, ``z = (f - f0) / u(f)`` is
Student-t distributed with the fit's effective degrees of freedom (normal
for white noise; the coverage of ``u(f)`` is tested in ``tests/sinefit``),
so ``|z|`` beyond its two-sided 0.1 % quantile (3.29 for many degrees of
freedom) rejects ``f0``.  A
phase quoted at ``f0`` is then off by about ``pi (f - f0) T``, i.e. by ``z``
times its own scale, which its U does not contain.  When the free fit
fails (too short, too noisy), the periodogram peak is compared instead,
with one frequency bin ``1 / T`` as the tolerance.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import named

__all__ = ["FREQUENCY_WARNING", "Z_REJECT", "frequency_mismatch", "rejection_limit"]

FREQUENCY_WARNING = "frequency-mismatch"

#: Two-sided 0.1 % quantile of the standard normal: the given frequency is rejected beyond it.
Z_REJECT = 3.29


def rejection_limit(dof: float) -> float:
    """Two-sided 0.1 % quantile of Student's t with ``dof`` degrees of freedom (:data:`Z_REJECT` for many).

    With coloured noise ``u(f)`` rests on few effective degrees of freedom, and ``z`` is t-distributed.
    """
    if not (math.isfinite(dof) and dof > 0):
        return Z_REJECT
    from scipy import stats

    return max(Z_REJECT, float(stats.t.isf(0.0005, dof)))


def frequency_mismatch(y, t, freq: float, *, harmonics: int = 1, name: str = "") -> str | None:
    """A ``frequency-mismatch`` warning when ``freq`` is not the frequency of ``y``, else None.

    Parameters
    ----------
    y : array_like, shape (N,)
        One channel (finite samples).
    t : array_like, shape (N,)
        Time stamps, s.
    freq : float
        The frequency the user gave, Hz.
    harmonics : int
        Harmonics fitted with the fundamental (as in the fit being checked).
    name : str
        Channel name for the message.

    Returns
    -------
    str or None
    """
    from senscal.errors import SenscalError
    from senscal.sinefit import fit_sine

    y = np.asarray(y, dtype=float)
    t = np.asarray(t, dtype=float)
    who = f"channel {name!r}: " if name else ""
    fix = "check --freq (or omit it to estimate the frequency)"
    try:
        free = fit_sine(y, t, harmonics=harmonics)
        f, u = float(free.frequency), float(free.u_frequency)
        dof = float(getattr(free, "dof_effective", None) or free.dof)
    except (SenscalError, ValueError, FloatingPointError, np.linalg.LinAlgError):
        f, u, dof = float("nan"), float("nan"), float("nan")
    if math.isfinite(f) and math.isfinite(u) and u > 0:
        z = (f - freq) / u
        limit = rejection_limit(dof)
        if abs(z) <= limit:
            return None
        return named(FREQUENCY_WARNING, (
            f"{who}the data are at {f:.6g} Hz (u {u:.2g} Hz, free-frequency fit), not at --freq {freq:g} Hz "
            f"(z = {z:.3g}, beyond {limit:.3g}); amplitude and phase fitted at {freq:g} Hz are wrong and their "
            f"u does not say so: {fix}"))
    peak = _peak(y, t)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if not (math.isfinite(peak) and span > 0) or abs(peak - freq) <= 1.0 / span:
        return None
    return named(FREQUENCY_WARNING, (
        f"{who}the largest spectral peak is at {peak:.4g} Hz, more than one frequency bin (1/T = "
        f"{1.0 / span:.2g} Hz) from --freq {freq:g} Hz; amplitude and phase fitted at {freq:g} Hz are wrong and "
        f"their u does not say so: {fix}"))


def _peak(y: np.ndarray, t: np.ndarray) -> float:
    """Frequency (Hz) of the largest periodogram bin above 0 Hz (NaN for fewer than 8 samples)."""
    if y.size < 8:
        return float("nan")
    dt = float(np.median(np.diff(t)))
    if not (math.isfinite(dt) and dt > 0):
        return float("nan")
    spec = np.abs(np.fft.rfft(y - y.mean()))
    k = int(np.argmax(spec[1:])) + 1
    return k / (y.size * dt)
