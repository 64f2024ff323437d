"""Shock calibration: ISO 16063-22 (comparison with a reference accelerometer) and ISO 16063-13 (laser primary).

Every step is linear in the recorded samples (differentiation of the laser
signal, the stated low-pass filter, the local polynomial that finds a peak,
the DFT of a pulse), so the standard uncertainty of each result is computed
exactly from the noise of the *raw* channels: the result's weights are pushed
back through the processing (its adjoint) and combined with the raw noise's
autocovariance, estimated on the record before the pulse.

Peak values are the vertex of a 4th-degree polynomial fitted to the samples
above 80 % of the reference peak (both channels on the same samples); the
shock sensitivity is the ratio of the peaks (ISO 16063-22 clause 3), the
transfer function the ratio of the pulses' DFTs over the band where the
reference spectrum keeps at least 10 % of its low-frequency value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import DataError, InputError

__all__ = ["ShockPulse", "TransferFunction", "shock_pulses", "lowpass", "differentiate", "find_pulses",
           "ISO_DURATION_MS"]

ISO_DURATION_MS = (0.05, 10.0)  # half-sine durations of ISO 16063-22
PEAK_LEVEL = 0.8  # samples above this fraction of the reference peak are fitted
PEAK_DEGREE = 4
_Z999 = 3.2905  # two-sided 99.9 %

# five-point stencils (error O(h^4)): first and second derivative
_D1 = np.array([1.0, -8.0, 0.0, 8.0, -1.0]) / 12.0
_D2 = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / 12.0


# --- linear operators and their adjoints --------------------------------------------------------------------

def _lowpass_gain(n: int, fs: float, cutoff_hz: float, order: int) -> np.ndarray:
    f = np.fft.rfftfreq(n, 1.0 / fs)
    return 1.0 / (1.0 + (f / cutoff_hz) ** (2 * order))


def lowpass(x, fs: float, cutoff_hz: float | None, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass: gain ``1 / (1 + (f / fc)^(2 order))`` (an order-``order`` Butterworth run
    forwards and backwards; -6 dB at ``fc``), applied by FFT on the record mirrored at its ends.

    ``x`` may be 2-D (rows filtered alike).  The operator is symmetric away from the record's ends, so it
    is its own adjoint for weights that live on a pulse (the uncertainty propagation uses that).
    """
    x = np.asarray(x, float)
    if cutoff_hz is None:
        return x.copy()
    n = x.shape[-1]
    pad = min(n - 1, n // 2 + 64)
    widths = [(0, 0)] * (x.ndim - 1) + [(pad, pad)]
    xp = np.pad(x, widths, mode="reflect")  # a mirror, not a held end value: no step for the filter to ring on
    g = _lowpass_gain(xp.shape[-1], fs, cutoff_hz, order)
    return np.fft.irfft(np.fft.rfft(xp, axis=-1) * g, xp.shape[-1], axis=-1)[..., pad:pad + n]


def _stencil(x, d):
    y = np.correlate(x, d, mode="same")
    y[:2] = y[2]
    y[-2:] = y[-3]
    return y


def differentiate(x, fs: float, order: int = 1) -> np.ndarray:
    """First (``order=1``) or second derivative by the five-point stencil (error ``O(h^4)``), per s or s^2."""
    x = np.asarray(x, float)
    if order == 1:
        return _stencil(x, _D1) * fs
    if order == 2:
        return _stencil(x, _D2) * fs * fs
    raise ValueError("order must be 1 or 2")


def _differentiate_adjoint(w, fs: float, order: int) -> np.ndarray:
    """``z[m] = sum_k d_k w[m - k]`` along the last axis (the stencil's transpose)."""
    d = _D1 * fs if order == 1 else _D2 * fs * fs
    w = np.asarray(w, float)
    z = np.zeros_like(w)
    L = w.shape[-1]
    for j, dk in enumerate(d):
        k = j - 2
        if k >= 0:
            z[..., k:] += dk * w[..., :L - k]
        else:
            z[..., :L + k] += dk * w[..., -k:]
    return z


@dataclass(frozen=True)
class _Chain:
    """Raw channel -> processed signal: optional differentiation, then the stated low-pass."""

    fs: float
    diff_order: int = 0
    cutoff_hz: float | None = None
    filter_order: int = 4

    def apply(self, x):
        y = differentiate(x, self.fs, self.diff_order) if self.diff_order else np.asarray(x, float)
        return lowpass(y, self.fs, self.cutoff_hz, self.filter_order)

    def adjoint(self, w):
        z = lowpass(w, self.fs, self.cutoff_hz, self.filter_order) if self.cutoff_hz is not None else w
        return _differentiate_adjoint(z, self.fs, self.diff_order) if self.diff_order else z

    @property
    def reach(self) -> int:
        """Samples beyond a weight's support that its raw weights reach (filter impulse response, stencil)."""
        return 4 + (int(8 * self.fs / self.cutoff_hz) + 16 if self.cutoff_hz else 0)

    def raw_var(self, noise: "_Noise", w, i0: int, n: int, scale: float, base: tuple[int, int]) -> np.ndarray:
        """Variance of ``w . processed`` (rows of ``w`` on samples ``i0 ...``) from the raw channel's noise.

        The zero line (mean of the processed samples ``base[0]:base[1]``) is subtracted from the signal
        first, so the weights are ``w`` minus their sum spread over the zero line's samples, pushed back
        through the processing.
        """
        w = np.atleast_2d(np.asarray(w, float))
        b0, b1 = base
        lo = max(min(i0, b0) - self.reach, 0)
        hi = min(max(i0 + w.shape[1], b1) + self.reach, n)
        seg = np.zeros((w.shape[0], hi - lo))
        seg[:, i0 - lo:i0 - lo + w.shape[1]] = w
        seg[:, b0 - lo:b1 - lo] -= (np.sum(w, axis=1) / (b1 - b0))[:, None]
        w_raw = self.adjoint(seg) * scale
        return noise.var(w_raw)


# --- noise ------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Noise:
    """Autocovariance of a raw channel's noise (lags 0..K; K = 0 when it passes as white)."""

    acov: np.ndarray
    n: int

    def var(self, w):
        """Variance of ``w . noise`` for the weights ``w`` (rows; the channel's sample spacing)."""
        w = np.asarray(w, float)
        v = self.acov[0] * np.sum(w * w, axis=-1)
        for k in range(1, self.acov.size):
            v = v + 2.0 * self.acov[k] * np.sum(w[..., :-k] * w[..., k:], axis=-1)
        return np.maximum(v, 0.0)

    def var_mean(self, m: int) -> float:
        """Variance of the mean of ``m`` consecutive samples."""
        return float(self.var(np.full(m, 1.0 / m)))


def _noise(x) -> _Noise:
    """Noise autocovariance of a pulse-free stretch (linear trend removed).

    White unless the first 10 autocorrelations exceed chance (Ljung-Box at 99.9 %); then lags up to the
    first whose correlation falls inside +/- 3.29 / sqrt(n) are kept, Bartlett-tapered.
    """
    from scipy.stats import chi2

    x = np.asarray(x, float)
    n = x.size
    t = np.arange(n) - 0.5 * (n - 1)
    r = x - x.mean() - t * (float(t @ (x - x.mean())) / float(t @ t))
    c0 = float(r @ r) / n
    if not c0 > 0:
        return _Noise(np.array([0.0]), n)
    kmax = min(10, n // 4)
    rho = np.array([float(r[:-k] @ r[k:]) / n / c0 for k in range(1, kmax + 1)])
    q = n * (n + 2) * float(np.sum(rho ** 2 / (n - np.arange(1, kmax + 1))))
    if q <= chi2.ppf(0.999, kmax):
        return _Noise(np.array([c0]), n)
    # lags up to four times the first that looks uncorrelated: a truncation or a taper there would drop the
    # correlation's tail, which is most of the long-run variance of smooth weights
    lim = _Z999 / math.sqrt(n)
    K = min(n // 10, 400)
    ac = np.array([c0] + [float(r[:-k] @ r[k:]) / n for k in range(1, K + 1)])
    small = np.flatnonzero(np.abs(ac[1:] / c0) < lim)
    k0 = int(small[0]) + 1 if small.size else K
    ac = ac[:min(4 * k0, K) + 1]
    # the removed mean and trend take about two long-run variances / n from every lag (and 1/n -> 1/(n-k))
    lr = ac[0] + 2.0 * float(np.sum(ac[1:]))
    ac = ac * n / (n - np.arange(ac.size)) + 2.0 * max(lr, 0.0) / n
    return _Noise(ac, n)


# --- pulses ---------------------------------------------------------------------------------------------------

def find_pulses(a, fs: float, *, min_sigma: float = 20.0, guard: int = 8) -> list[tuple[int, int, int]]:
    """``(start, peak, end)`` sample indices of the shock pulses in an acceleration signal.

    A pulse is a run above the larger of ``min_sigma`` robust noise sigmas and 20 % of the largest peak;
    its ends are where it falls to 2 % of its own peak.  The ``guard`` samples at either end (the
    differentiation's and the filter's end effects) hold no pulse.
    """
    a = np.asarray(a, float)
    x = a - float(np.median(a))
    guard = min(guard, x.size // 4)
    x[:guard] = 0.0  # the stencil's and filter's end samples are no pulse
    x[x.size - guard:] = 0.0
    sig = 1.4826 * float(np.median(np.abs(np.diff(x)))) / math.sqrt(2.0)
    amax = float(np.max(np.abs(x)))
    if not amax > 0:
        return []
    pol = 1.0 if float(np.max(x)) >= -float(np.min(x)) else -1.0
    s = pol * x
    thr = max(min_sigma * sig, 0.2 * float(np.max(s)))
    runs: list[tuple[int, int, int]] = []
    n = s.size
    idx = np.flatnonzero(s > thr)
    if idx.size == 0:
        return []
    splits = np.flatnonzero(np.diff(idx) > 1)
    lo = np.concatenate([[idx[0]], idx[splits + 1]])
    hi = np.concatenate([idx[splits], [idx[-1]]])
    for a0, a1 in zip(lo, hi):
        pk = int(a0 + np.argmax(s[a0:a1 + 1]))
        lvl = 0.02 * s[pk]
        st = pk
        while st > 0 and s[st - 1] > lvl:
            st -= 1
        en = pk
        while en < n - 1 and s[en + 1] > lvl:
            en += 1
        if runs and st <= runs[-1][2]:
            continue  # the same pulse (a ring back above the threshold)
        runs.append((st, pk, en))
    return runs


def _peak(y, idx: np.ndarray, centre: int):
    """Vertex of the degree-4 polynomial through ``y[idx]``: (value, time offset in samples, weights)."""
    t = (idx - centre).astype(float)
    h = max(float(np.max(np.abs(t))), 1.0)
    X = np.vander(t / h, PEAK_DEGREE + 1, increasing=True)
    P = np.linalg.solve(X.T @ X, X.T)  # coefficients = P @ y
    c = P @ y[idx]
    grid = np.linspace(-1.0, 1.0, 401)
    vals = np.polynomial.polynomial.polyval(grid, c)
    pol = 1.0 if c[0] >= 0 else -1.0
    k = int(np.argmax(pol * vals))
    u = grid[k]
    dc = np.polynomial.polynomial.polyder(c)
    d2 = np.polynomial.polynomial.polyder(dc)
    for _ in range(20):  # Newton on the derivative from the grid's best point
        g2 = np.polynomial.polynomial.polyval(u, d2)
        if g2 == 0:
            break
        step = np.polynomial.polynomial.polyval(u, dc) / g2
        u = min(1.0, max(-1.0, u - step))
        if abs(step) < 1e-12:
            break
    value = float(np.polynomial.polynomial.polyval(u, c))
    # at an interior vertex d(peak)/dc_j = u^j (the vertex's shift does not change the value to first order)
    w = (u ** np.arange(PEAK_DEGREE + 1)) @ P
    return value, u * h, w


def _shape_pvalue(e, eb, idx: np.ndarray, centre: int) -> float:
    """P-value of the residual of ``e`` (output minus the scaled acceleration) about the peak polynomial.

    With the pulse's shape kept, ``e`` over the peak samples is noise plus a smooth remainder the
    polynomial absorbs; a resonance's ringing is not smooth.  The residual power is compared with its
    expectation under the noise of ``eb`` (the same combination before the pulse, its sample
    autocovariance as a Toeplitz covariance): ``T / E`` against a scaled chi-square with the
    Satterthwaite degrees of freedom.
    """
    from scipy.linalg import toeplitz
    from scipy.stats import chi2

    t = (idx - centre).astype(float)
    h = max(float(np.max(np.abs(t))), 1.0)
    X = np.vander(t / h, PEAK_DEGREE + 1, increasing=True)
    M = np.eye(idx.size) - X @ np.linalg.solve(X.T @ X, X.T)
    r = M @ e
    eb = eb - eb.mean()
    N, nb = idx.size, eb.size
    acov = np.array([float(eb[:nb - k] @ eb[k:]) / nb if k < nb else 0.0 for k in range(N)])
    MS = M @ toeplitz(acov)
    E = float(np.trace(MS))
    V = 2.0 * float(np.sum(MS * MS.T))
    if not (E > 0 and V > 0):
        return 1.0
    nu = 2.0 * E * E / V
    return float(chi2.sf(float(r @ r) / E * nu, nu))


@dataclass(frozen=True)
class TransferFunction(ResultMixin):
    """Complex sensitivity from one pulse: DUT output per m/s^2 at ``frequency_hz``.

    Attributes
    ----------
    frequency_hz, magnitude, u_magnitude, phase_deg, u_phase_deg : ndarray
        Magnitude (output per m/s^2) and phase (DUT minus acceleration, deg; negative for a lag), with
        standard u (noise propagated).
    """

    frequency_hz: np.ndarray
    magnitude: np.ndarray
    u_magnitude: np.ndarray
    phase_deg: np.ndarray
    u_phase_deg: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {k: [float(v) for v in getattr(self, k)] for k in
                ("frequency_hz", "magnitude", "u_magnitude", "phase_deg", "u_phase_deg")}


@dataclass(frozen=True)
class ShockPulse(ResultMixin):
    """Shock sensitivity from one pulse.

    Attributes
    ----------
    index : int
        Pulse number in its record (0 first).
    t_peak_s : float
        Time of the reference peak, s from the record's start.
    duration_ms : float
        Pulse duration (2 % to 2 % of the peak), ms.
    peak_acceleration, u_peak_acceleration : float
        Peak acceleration (m/s^2) and its standard u.
    peak_output : float
        Peak of the DUT's output (its unit).
    sensitivity, u_sensitivity : float
        Peak ratio: DUT output per m/s^2, standard u (k=1).
    budget : dict
        ``{component: {"type": "A"|"B", "u_rel": ...}}``.
    transfer_function : TransferFunction
    zero_shift : float
        DUT output after the pulse minus before (its unit); corrected for when significant.
    ringing_ratio : float
        Residual power of ``DUT - S ref`` over the pulse and its settling relative to the noise (about 1
        for matching shapes; informative, the ``shock-ringing`` warning compares the peak ratio with the
        low-frequency transfer function).
    warnings : tuple of str
    """

    index: int
    t_peak_s: float
    duration_ms: float
    peak_acceleration: float
    u_peak_acceleration: float
    peak_output: float
    sensitivity: float
    u_sensitivity: float
    budget: dict
    transfer_function: TransferFunction
    zero_shift: float
    ringing_ratio: float
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "t_peak_s": self.t_peak_s, "duration_ms": self.duration_ms,
                "peak_acceleration": self.peak_acceleration, "u_peak_acceleration": self.u_peak_acceleration,
                "peak_output": self.peak_output, "sensitivity": self.sensitivity,
                "u_sensitivity": self.u_sensitivity, "budget": {k: dict(v) for k, v in self.budget.items()},
                "transfer_function": self.transfer_function.to_dict(), "zero_shift": self.zero_shift,
                "ringing_ratio": self.ringing_ratio, "warnings": list(self.warnings)}


def _check_inputs(ref, out, fs, cutoff_hz, filter_order):
    r = np.asarray(ref, float)
    o = np.asarray(out, float)
    if r.ndim != 1 or r.shape != o.shape:
        raise InputError("the reference (or laser) and output channels must be one-dimensional and of equal length")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(o))):
        raise DataError("NaN or inf in the shock recording: cut them out with --start/--stop")
    if not (fs > 0 and math.isfinite(fs)):
        raise InputError(f"the sample rate must be a positive number of Hz, got {fs!r}")
    if cutoff_hz is not None and not (0 < cutoff_hz < fs / 2):
        raise InputError(f"--lowpass-hz {cutoff_hz:g} must lie between 0 and the Nyquist frequency {fs / 2:g} Hz")
    if int(filter_order) < 1:
        raise InputError("--lowpass-order must be at least 1")
    return r, o


def shock_pulses(ref, out, fs: float, *, reference_sensitivity: float | None = None, laser: str | None = None,
                 u_reference_rel: float = 0.0, u_other_rel: float = 0.0, cutoff_hz: float | None = None,
                 filter_order: int = 4, n_freqs: int = 8) -> list[ShockPulse]:
    """Shock sensitivity (peak ratio) and transfer function of every pulse in one record.

    Parameters
    ----------
    ref : array_like, shape (N,)
        ISO 16063-22: the reference accelerometer's output (with ``reference_sensitivity``).
        ISO 16063-13: the laser's velocity (m/s, ``laser="velocity"``) or displacement (m,
        ``laser="displacement"``).
    out : array_like, shape (N,)
        The accelerometer's output (its unit is the sensitivity's numerator).
    fs : float
        Sample rate, Hz.
    reference_sensitivity : float, optional
        Reference output per m/s^2 (comparison).
    laser : {"velocity", "displacement"}, optional
        Primary calibration: what the laser channel measures; differentiated by the five-point stencil.
    u_reference_rel : float
        Relative standard u of the reference sensitivity (type B, comparison).
    u_other_rel : float
        Other relative standard u (type B: transverse motion, mounting, amplitude linearity ...).
    cutoff_hz, filter_order : float, int
        The stated low-pass, applied alike to the acceleration and the output (ISO 16063-13 5.4, -22 6.5):
        zero-phase Butterworth of ``filter_order``, -6 dB at ``cutoff_hz``; none when None.
    n_freqs : int
        Frequencies of the transfer function.

    Returns
    -------
    list of ShockPulse

    Raises
    ------
    InputError, DataError
        No pulse, a pulse too short for the sample rate, no baseline before it, a clipped pulse, bad options.
    """
    r_raw, o_raw = _check_inputs(ref, out, fs, cutoff_hz, filter_order)
    if (laser is None) == (reference_sensitivity is None):
        raise InputError("give either a reference sensitivity (ISO 16063-22 comparison) or the laser quantity "
                         "(ISO 16063-13 primary: velocity or displacement)")
    if laser is not None and laser not in ("velocity", "displacement"):
        raise InputError(f"--laser must be velocity or displacement, got {laser!r}")
    if reference_sensitivity is not None and not (math.isfinite(reference_sensitivity) and reference_sensitivity != 0):
        raise InputError(f"--reference-sensitivity must be a non-zero number, got {reference_sensitivity!r}")
    for name, v in (("--u-reference", u_reference_rel), ("--u-other", u_other_rel)):
        if not (math.isfinite(v) and 0 <= v < 1):
            raise InputError(f"{name} must be a relative standard uncertainty in [0, 1), got {v!r}")
    d_order = {None: 0, "velocity": 1, "displacement": 2}[laser]
    scale = 1.0 if laser else 1.0 / float(reference_sensitivity)
    cref = _Chain(fs, d_order, cutoff_hz, int(filter_order))
    cout = _Chain(fs, 0, cutoff_hz, int(filter_order))
    acc = cref.apply(r_raw) * scale
    y = cout.apply(o_raw)
    edge = 8 + (int(4 * fs / cutoff_hz) if cutoff_hz else 0)
    pulses = find_pulses(acc, fs, guard=edge)
    if not pulses:
        hint = ("; the laser's derivative needs the stated low-pass (--lowpass-hz, e.g. 10 / T)"
                if laser and cutoff_hz is None else "")
        raise DataError("no shock pulse in the reference: check --reference/--laser and that the record holds a "
                        f"pulse 20 times above the noise{hint}")
    out_list = []
    n = acc.size
    for j, (st, pk, en) in enumerate(pulses):
        out_list.append(_one_pulse(j, st, pk, en, pulses, acc, y, r_raw, o_raw, cref, cout, scale, fs, n,
                                   u_reference_rel if laser is None else 0.0, u_other_rel, laser, n_freqs))
    return out_list


def _one_pulse(j, st, pk, en, pulses, acc, y, r_raw, o_raw, cref, cout, scale, fs, n, u_ref_rel, u_other_rel,
               laser, n_freqs) -> ShockPulse:
    warnings: list[str] = []
    T = (en - st) / fs
    dur_ms = 1e3 * T
    lo_ms, hi_ms = ISO_DURATION_MS
    if not lo_ms * 0.8 <= dur_ms <= hi_ms * 1.25:
        warnings.append(named("pulse-duration", f"pulse {j} lasts {dur_ms:.3g} ms, outside the 0.05-10 ms of "
                              "ISO 16063-22: the sensitivity holds for this pulse only"))
    width = en - st
    # baseline before the pulse (after the previous one has settled), margins of a fifth of the pulse
    margin = max(8, width // 5)
    # the record's first samples carry the stencil's and the filter's end effects
    edge = 8 + (int(4 * fs / cref.cutoff_hz) if cref.cutoff_hz else 0)
    prev_end = pulses[j - 1][2] + 3 * (pulses[j - 1][2] - pulses[j - 1][0]) + margin if j else 0
    b0, b1 = max(prev_end, min(edge, (st - margin) // 2)), st - margin
    if b1 - b0 < 64:
        raise DataError(f"pulse {j} at {pk / fs:.4g} s has {max(b1 - b0, 0)} samples of quiet record before it; "
                        "at least 64 are needed for the noise and the zero line (record longer before the shock)")
    nxt = pulses[j + 1][0] - margin if j + 1 < len(pulses) else n - edge
    # the zero after the pulse: the end of the quiet stretch that follows it (ringing has decayed there)
    a1 = nxt
    a0 = max(en + 3 * width + margin, a1 - (b1 - b0))
    pol = 1.0 if acc[pk] >= 0 else -1.0
    # a clipped pulse: several samples within 1e-9 of the raw extreme
    for name, raw in (("reference", r_raw), ("output", o_raw)):
        seg = raw[st:en + 1]
        ext = float(np.max(np.abs(seg)))
        if ext > 0 and int(np.sum(np.abs(np.abs(seg) - ext) <= 1e-9 * ext)) >= 3 and laser is None:
            raise DataError(f"the {name} channel is clipped at {ext:g} in pulse {j} (flat top): lower the "
                            "amplifier gain or the shock level")
    nz_r = _noise(r_raw[b0:b1])
    nz_o = _noise(o_raw[b0:b1])
    acc_b = acc - float(np.mean(acc[b0:b1]))
    y_b = y - float(np.mean(y[b0:b1]))
    # zero shift of the DUT (a known piezoelectric effect): output after the pulse minus before
    shift, u_shift = 0.0, 0.0
    cum = None
    if a1 - a0 >= 32:
        shift = float(np.mean(o_raw[a0:a1]) - np.mean(o_raw[b0:b1]))
        u_shift = math.sqrt(nz_o.var_mean(a1 - a0) + nz_o.var_mean(b1 - b0))
        if abs(shift) > _Z999 * u_shift:
            # the shift builds up with the pulse (its cumulative area); removed from the output on that model,
            # the model's own doubt (a step anywhere inside the pulse) stays in the budget
            area = np.cumsum(np.clip(pol * acc_b[st:en + 1], 0.0, None))
            cum = np.concatenate([np.zeros(st), area / area[-1], np.ones(n - en - 1)])
            y_b = y_b - shift * cum
            warnings.append(named("zero-shift", f"the output's zero shifted by {shift:.3g} across pulse {j} "
                                  f"({abs(shift) / max(abs(y_b[pk]), 1e-300):.2%} of its peak); corrected as "
                                  "growing with the pulse, half of it in u"))
        else:
            shift = 0.0
    # peak values on the samples above 80 % of the reference peak
    lvl = PEAK_LEVEL * pol * acc_b[pk]
    i0 = pk
    while i0 > st and pol * acc_b[i0 - 1] > lvl:
        i0 -= 1
    i1 = pk
    while i1 < en and pol * acc_b[i1 + 1] > lvl:
        i1 += 1
    idx = np.arange(i0, i1 + 1)
    if idx.size < 2 * (PEAK_DEGREE + 1):
        raise DataError(f"pulse {j} has {idx.size} samples above 80 % of its peak; at least {2 * (PEAK_DEGREE + 1)} "
                        f"are needed (raise the sample rate above {fs * 2 * (PEAK_DEGREE + 1) / max(idx.size, 1):.3g} Hz)")
    pa, _, wa = _peak(acc_b, idx, pk)
    po, _, wo = _peak(y_b, idx, pk)
    sens = po / pa

    var_pa = float(cref.raw_var(nz_r, wa, int(idx[0]), n, scale, (b0, b1))[0])
    var_po = float(cout.raw_var(nz_o, wo, int(idx[0]), n, 1.0, (b0, b1))[0])
    if cum is not None:
        var_po += (u_shift * cum[pk]) ** 2
    u_pa_rel = math.sqrt(var_pa) / abs(pa)
    u_po_rel = math.sqrt(var_po) / abs(po) if po else float("inf")
    budget = {
        "reference_peak" if laser is None else "laser_peak": {"type": "A", "u_rel": u_pa_rel},
        "output_peak": {"type": "A", "u_rel": u_po_rel},
        "reference_sensitivity": {"type": "B", "u_rel": float(u_ref_rel)},
        "zero_shift": {"type": "B", "u_rel": abs(shift) * 0.5 / math.sqrt(3.0) / abs(po) if cum is not None else 0.0},
        "other": {"type": "B", "u_rel": float(u_other_rel)},
    }
    u_rel = math.sqrt(sum(v["u_rel"] ** 2 for v in budget.values()))
    # ringing: the residual DUT - S a over the pulse and its settling against the noise of the same combination
    eb = y_b[b0:b1] - sens * acc_b[b0:b1]
    eb = eb - eb.mean()
    w0, w1 = max(st - margin, 0), min(en + 3 * width + margin, a0, n)
    # the window reaches past the pulse as long as the residual (ringing) stands above the noise
    # (a ringing that decays exponentially is still half its threshold level as long again after it first
    # falls under it: the window takes that too, so that the truncated tail is far under the noise)
    blk = max(width // 2, 16)
    s_e = float(np.sqrt(np.mean(eb * eb)))
    k = en
    last = None
    while k + blk <= min(a0, n):
        if float(np.sqrt(np.mean((y_b[k:k + blk] - sens * acc_b[k:k + blk]) ** 2))) > 1.5 * s_e:
            last = k + blk
        k += blk
    if last is not None:
        w1 = max(w1, min(last + (last - en) + margin, a0, n))
    e = y_b[w0:w1] - sens * acc_b[w0:w1]
    c0 = float(eb @ eb) / max(eb.size, 1)
    ratio = float(e @ e) / (e.size * c0) if c0 > 0 else float("nan")
    tf, u_h_noise = _transfer(acc_b, y_b, w0, w1, width, n, fs, cref, cout, nz_r, nz_o, scale, (b0, b1), n_freqs,
                              u_rel_b=math.hypot(u_ref_rel, u_other_rel))
    # ringing: with the pulse's shape kept, the peak ratio equals the transfer function at the pulse's low
    # frequencies; a resonance the pulse excites moves the peaks and not the low-frequency ratio
    dep = abs(sens) / float(tf.magnitude[0]) - 1.0
    u_dep = math.sqrt(u_pa_rel ** 2 + u_po_rel ** 2 + float(u_h_noise[0]) ** 2)
    p_shape = _shape_pvalue(y_b[idx] - sens * acc_b[idx], eb, idx, pk)
    if abs(dep) > _Z999 * u_dep or p_shape < 1e-3:
        warnings.append(named("shock-ringing", f"pulse {j}: the peak ratio departs from the low-frequency transfer "
                              f"function by {dep:+.3%} ({abs(dep) / u_dep:.1f} u) or rings about its peak (p = "
                              f"{p_shape:.2g}): the sensor's resonance rings or the pulse's shape differs, so the peak "
                              "ratio holds for this pulse only; state a low-pass (--lowpass-hz) below the resonance, "
                              "or quote the transfer function"))
    return ShockPulse(index=j, t_peak_s=pk / fs, duration_ms=dur_ms, peak_acceleration=pa,
                      u_peak_acceleration=abs(pa) * u_pa_rel, peak_output=po, sensitivity=sens,
                      u_sensitivity=abs(sens) * u_rel, budget=budget, transfer_function=tf, zero_shift=shift,
                      ringing_ratio=ratio, warnings=tuple(warnings))


def _transfer(acc_b, y_b, w0, w1, width, n, fs, cref, cout, nz_r, nz_o, scale, base, n_freqs,
              u_rel_b) -> tuple[TransferFunction, np.ndarray]:
    """H(f) = Y(f) / A(f) over the pulse and its settling, on the band where |A| keeps 10 % of |A(0)|; also the
    relative u of |H| from the noise alone."""
    a = acc_b[w0:w1]
    yy = y_b[w0:w1]
    m = a.size
    a0 = abs(float(np.sum(a)))
    nfft = 1 << int(math.ceil(math.log2(max(16 * m, 4096))))
    mag = np.abs(np.fft.rfft(a, nfft))[1:]
    fgrid = np.fft.rfftfreq(nfft, 1.0 / fs)[1:]
    below = np.flatnonzero(mag < 0.1 * a0)
    f_max = float(fgrid[below[0] - 1]) if below.size and below[0] > 0 else float(fgrid[-1])
    freqs = np.geomspace(0.02 * f_max, f_max, n_freqs)
    t = np.arange(m) / fs
    ph = 2 * math.pi * np.outer(freqs, t)
    c, s = np.cos(ph), -np.sin(ph)
    A = c @ a + 1j * (s @ a)
    Y = c @ yy + 1j * (s @ yy)
    H = Y / A
    var_rel = np.zeros(n_freqs)
    var_ph = np.zeros(n_freqs)
    for X, chain, nz, fac in ((Y, cout, nz_o, 1.0), (A, cref, nz_r, scale)):
        th = np.angle(X)[:, None]
        ax = np.abs(X)[:, None]
        # d(ln X) = dX conj(X) / |X|^2: its real part moves the magnitude, its imaginary part the phase
        wr = (c * np.cos(th) + s * np.sin(th)) / ax
        wi = (s * np.cos(th) - c * np.sin(th)) / ax
        v = chain.raw_var(nz, np.vstack([wr, wi]), w0, n, fac, base)
        var_rel += v[:n_freqs]
        var_ph += v[n_freqs:]
    u_mag = np.abs(H) * np.sqrt(var_rel + u_rel_b ** 2)
    u_ph = np.degrees(np.sqrt(var_ph))
    return TransferFunction(frequency_hz=freqs, magnitude=np.abs(H), u_magnitude=u_mag,
                            phase_deg=np.degrees(np.angle(H)), u_phase_deg=u_ph), np.sqrt(var_rel)
