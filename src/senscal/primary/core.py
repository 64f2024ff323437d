"""Heydemann correction and the sine-approximation method of ISO 16063-11 (method 3).

Model of the quadrature signals (homodyne interferometer, phase ``phi = 4 pi s / lambda``
for the displacement ``s``)::

    I = p + a cos(phi)
    Q = q + b sin(phi + alpha)

with offsets ``p, q``, gain ratio ``g = b / a`` and quadrature phase error
``alpha`` (Heydemann 1981).  The corrected pair is ``c = (I - p) / a = cos(phi)``
and ``s = ((Q - q) / g / a - c sin(alpha)) / cos(alpha) = sin(phi)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import DataError, InputError

__all__ = ["HeydemannFit", "PrimaryPoint", "FringeCount", "heydemann_fit", "corrected_phase", "calibrate_point",
           "check_wavelength", "fringe_count"]

HEYDEMANN_NAMES = ("offset_i", "offset_q", "gain_ratio", "quadrature_error_rad")


@dataclass(frozen=True)
class HeydemannFit(ResultMixin):
    """Ellipse parameters of the quadrature pair.

    Attributes
    ----------
    offset_i, offset_q : float
        Offsets ``p``, ``q`` (units of the signals).
    gain_ratio : float
        ``g = b / a`` (1 for a perfect pair).
    quadrature_error_rad : float
        ``alpha``, rad (0 for a perfect pair).
    amplitude_i : float
        ``a`` (units of the signals).
    covariance : ndarray, shape (4, 4)
        Covariance of (offset_i, offset_q, gain_ratio, quadrature_error_rad).
    radius_rms : float
        RMS of the corrected radius minus 1 (relative ellipse residual).
    """

    offset_i: float
    offset_q: float
    gain_ratio: float
    quadrature_error_rad: float
    amplitude_i: float
    covariance: np.ndarray = field(repr=False)
    radius_rms: float = float("nan")

    @property
    def params(self) -> np.ndarray:
        return np.array([self.offset_i, self.offset_q, self.gain_ratio, self.quadrature_error_rad])

    @property
    def u(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def to_dict(self) -> dict[str, Any]:
        u = self.u
        return {"offset_i": self.offset_i, "u_offset_i": u[0], "offset_q": self.offset_q, "u_offset_q": u[1],
                "gain_ratio": self.gain_ratio, "u_gain_ratio": u[2],
                "quadrature_error_deg": math.degrees(self.quadrature_error_rad), "u_quadrature_error_deg":
                math.degrees(u[3]), "amplitude_i": self.amplitude_i, "radius_rms": self.radius_rms}


def _conic_to_params(theta: np.ndarray) -> np.ndarray:
    """(p, q, g, alpha, a) of the conic ``A x^2 + B y^2 + C xy + D x + E y = 1`` (normalised coordinates)."""
    A, B, C, D, E = theta
    m = np.array([[2 * A, C], [C, 2 * B]])
    p, q = np.linalg.solve(m, -np.array([D, E]))
    # value of the quadratic form on the ellipse, centred: A x^2 + B y^2 + C xy = 1 + A p^2 + B q^2 + C p q
    k = 1.0 + A * p * p + B * q * q + C * p * q
    if not (A > 0 and B > 0 and k > 0 and 4 * A * B - C * C > 0):
        raise DataError("the quadrature signals do not lie on an ellipse: not a quadrature pair "
                        "(give the two quadrature outputs of the interferometer with --quadrature I,Q)")
    sin_a = -C / (2.0 * math.sqrt(A * B))
    alpha = math.asin(max(-1.0, min(1.0, sin_a)))
    g = math.sqrt(A / B)
    # A / k = 1 / (a^2 cos^2 alpha)
    a = math.sqrt(k / A) / math.cos(alpha)
    return np.array([p, q, g, alpha, a])


def _heydemann(i_sig, q_sig) -> tuple[HeydemannFit, np.ndarray]:
    """:func:`heydemann_fit` and the corrected radius of each sample (relative to the I amplitude).

    The radius is what the intensity check reads next: returned, it is not computed twice (issue 28).

    Returns
    -------
    (HeydemannFit, ndarray)
        The fit, and the corrected radius ``sqrt(c^2 + s^2)`` of each sample (1 on the fitted ellipse).

    Raises
    ------
    DataError
        A single channel given twice (the pair lies on a line), or no ellipse.
    """
    x = np.asarray(i_sig, float)
    y = np.asarray(q_sig, float)
    mx, my = float(np.mean(x)), float(np.mean(y))
    sx, sy = float(np.std(x)), float(np.std(y))
    if not (sx > 0 and sy > 0):
        raise DataError("a quadrature channel is constant: give the two quadrature outputs with --quadrature I,Q")
    if not (math.isfinite(sx) and math.isfinite(sy)):
        raise DataError("the quadrature signals overflow the float range (values near 1e300): rescale the I and Q "
                        "channels")
    xn, yn = (x - mx) / sx, (y - my) / sy
    r = abs(float(np.mean(xn * yn)))
    if r > 0.995:
        raise DataError(f"the I and Q channels are one signal (correlation {r:.4f}): a single channel is not a "
                        "quadrature pair; give both quadrature outputs with --quadrature I,Q")
    # the five columns as contiguous rows (no strided copy of a million-row matrix)
    R = np.empty((5, xn.size))
    np.multiply(xn, xn, out=R[0])
    np.multiply(yn, yn, out=R[1])
    np.multiply(xn, yn, out=R[2])
    R[3], R[4] = xn, yn
    X = R.T
    # normal equations of five columns in normalised coordinates (well conditioned): a fifth of lstsq's time
    # on a million samples, the same estimate
    gram = R @ X
    theta = np.linalg.solve(gram, R.sum(axis=1))
    res = X @ theta - 1.0
    n = xn.size
    s2 = float(res @ res) / max(n - 5, 1)
    cov_t = s2 * np.linalg.inv(gram)
    pn = _conic_to_params(theta)
    jac = np.empty((5, 5))
    for j in range(5):
        h = 1e-6 * max(abs(theta[j]), 1e-3)
        tp = theta.copy()
        tp[j] += h
        tm = theta.copy()
        tm[j] -= h
        jac[:, j] = (_conic_to_params(tp) - _conic_to_params(tm)) / (2 * h)
    cov_n = jac @ cov_t @ jac.T
    # back to the signals' units: p = mx + sx pn, q = my + sy qn, g = g_n sy / sx, alpha unchanged
    scale = np.array([sx, sy, sy / sx, 1.0])
    params = np.array([mx + sx * pn[0], my + sy * pn[1], pn[2] * sy / sx, pn[3]])
    cov = cov_n[:4, :4] * np.outer(scale, scale)
    fit = HeydemannFit(offset_i=float(params[0]), offset_q=float(params[1]), gain_ratio=float(params[2]),
                       quadrature_error_rad=float(params[3]), amplitude_i=float(pn[4] * sx), covariance=cov)
    c, s = _corrected(x, y, params, fit.amplitude_i)
    rad = np.sqrt(c * c + s * s)
    return HeydemannFit(offset_i=fit.offset_i, offset_q=fit.offset_q, gain_ratio=fit.gain_ratio,
                        quadrature_error_rad=fit.quadrature_error_rad, amplitude_i=fit.amplitude_i,
                        covariance=cov, radius_rms=float(np.sqrt(np.mean((rad - 1.0) ** 2)))), rad


def heydemann_fit(i_sig, q_sig) -> HeydemannFit:
    """Fit the ellipse of a quadrature pair (linear least squares on the conic).

    Parameters
    ----------
    i_sig, q_sig : array_like, shape (N,)
        The two quadrature signals (any unit, the same for both).

    Returns
    -------
    HeydemannFit
        Offsets, gain ratio, quadrature error and their covariance (the
        conic's least-squares covariance propagated by a numerical Jacobian).

    Raises
    ------
    DataError
        A single channel given twice (the pair lies on a line), or no ellipse.
    """
    return _heydemann(i_sig, q_sig)[0]


def _corrected(x, y, params, a: float = 1.0):
    p, q, g, alpha = params
    # the same operations in place: two record-long arrays instead of five (a million samples, issue 28)
    c = np.subtract(x, p)
    c /= a
    s = np.subtract(y, q)
    s /= g * a
    s -= c * math.sin(alpha)
    s /= math.cos(alpha)
    return c, s


def corrected_phase(i_sig, q_sig, params) -> np.ndarray:
    """Unwrapped interferometer phase (rad) of the pair corrected with ``params`` (p, q, g, alpha)."""
    c, s = _corrected(np.asarray(i_sig, float), np.asarray(q_sig, float), params)
    return np.unwrap(np.arctan2(s, c))


def check_wavelength(wavelength_nm: float) -> None:
    """Refuse a wavelength that is not in nanometres (a value in metres, or a typo)."""
    w = float(wavelength_nm)
    if not math.isfinite(w) or w <= 0:
        raise InputError(f"--wavelength-nm must be a positive number of nanometres, got {wavelength_nm!r}")
    if w < 1e-3:
        raise InputError(f"--wavelength-nm {w:g} looks like metres: give nanometres (632.8 for a HeNe laser)")
    if not 150.0 <= w <= 20000.0:
        raise InputError(f"--wavelength-nm {w:g} is not a laser wavelength in nm (632.8 for a HeNe laser)")


@dataclass(frozen=True)
class FringeCount(ResultMixin):
    """Displacement amplitude by fringe counting (ISO 16063-11 method 1), the magnitude cross-check.

    Attributes
    ----------
    displacement_m, u_displacement_m : float
        ``lambda N / (16 M)`` from ``N`` zero crossings of the offset-free I signal over ``M`` whole
        periods; u from the count's resolution (each half-period's count is off by less than one
        crossing, rectangular), m.
    crossings : int
    periods : int
    sensitivity, u_sensitivity : float
        The output's fundamental per m/s^2 of ``(2 pi f)^2`` times this displacement.
    difference_rel : float
        Sine approximation's sensitivity over this one, minus 1.
    applies : bool
        The count resolves the displacement to 1e-3 (at least 577 crossings a half period); below,
        fringe counting is too coarse to check the magnitude.
    """

    displacement_m: float
    u_displacement_m: float
    crossings: int
    periods: int
    sensitivity: float
    u_sensitivity: float
    difference_rel: float
    applies: bool


FRINGE_RESOLUTION = 1e-3  # relative u of the count below which the cross-check applies


def fringe_count(i_sig, fs: float, freq: float, wavelength_nm: float, *, offset: float | None = None,
                 amplitude: float | None = None, hysteresis: float = 0.02) -> tuple[float, float, int, int]:
    """Displacement amplitude from the zero crossings of one interferometer signal (ISO 16063-11 method 1).

    Parameters
    ----------
    i_sig : array_like, shape (N,)
        One interferometer output (``p + a cos(4 pi s / lambda)``).
    fs, freq : float
        Sample rate and excitation frequency, Hz.
    wavelength_nm : float
    offset, amplitude : float, optional
        ``p`` and ``a`` (from the Heydemann fit); estimated from the signal's extremes when omitted.
    hysteresis : float
        A crossing counts when the signal goes from below ``-h a`` to above ``+h a`` or back, so that noise
        near a turning point does not chatter; a turning point within ``asin(h) / pi`` of a crossing may
        lose it, which widens each half period's count error to ``1 + 2 asin(h) / pi``.

    Returns
    -------
    (displacement_m, u_displacement_m, crossings, periods)
        Over the whole periods from the record's start; each half period's count is off by less than one
        crossing (rectangular, the same every half period when the motion is steady), the record's ends
        by less than one.
    """
    x = np.asarray(i_sig, float)
    p = 0.5 * (float(x.max()) + float(x.min())) if offset is None else float(offset)
    a = 0.5 * float(np.ptp(x)) if amplitude is None else float(amplitude)
    m = int(math.floor(x.size * freq / fs))
    if m < 1:
        raise DataError("fringe counting needs at least one whole period of the vibration in the record")
    seg = x[:int(round(m * fs / freq))] - p
    h = hysteresis * abs(a)
    state = np.where(seg > h, 1, np.where(seg < -h, -1, 0))
    state = state[state != 0]
    n = int(np.count_nonzero(np.diff(state)))
    lam = wavelength_nm * 1e-9
    disp = lam * n / (16.0 * m)
    half = max(n / (2.0 * m), 1e-300)
    width = 1.0 + 2.0 * math.asin(min(hysteresis, 1.0)) / math.pi
    u_rel = math.sqrt(width * width / (3.0 * half * half) + 1.0 / (3.0 * max(n, 1) ** 2))
    return disp, disp * u_rel, n, m


@dataclass(frozen=True)
class PrimaryPoint(ResultMixin):
    """Sensitivity of an accelerometer at one frequency against the interferometer.

    Attributes
    ----------
    frequency_hz : float
    sensitivity, u_sensitivity : float
        Output amplitude per m/s^2 of acceleration, standard u (k=1).
    phase_deg, u_phase_deg : float
        Output phase minus acceleration phase, deg (negative for a lag).
    displacement_m, acceleration : float
        Displacement amplitude (m) and acceleration amplitude (m/s^2).
    fringes : float
        Peak-to-peak interferometer phase / 2 pi.
    heydemann : HeydemannFit
    budget : dict
        ``{component: {"u_rel": ..., "u_phase_deg": ..., "type": "A"|"B"}}``.
    residual : dict
        Residual RMS of the displacement (m) and output fits, the ellipse residual.
    slices : int
        Number of per-period (sliced) fits.
    fringe_count : FringeCount or None
        Fringe counting's magnitude cross-check (None where the record holds under one period).
    warnings : tuple of str
    """

    frequency_hz: float
    sensitivity: float
    u_sensitivity: float
    phase_deg: float
    u_phase_deg: float
    displacement_m: float
    acceleration: float
    fringes: float
    heydemann: HeydemannFit
    budget: dict
    residual: dict
    slices: int
    fringe_count: FringeCount | None = None
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {"frequency_hz": self.frequency_hz, "sensitivity": self.sensitivity,
                "u_sensitivity": self.u_sensitivity, "phase_deg": self.phase_deg, "u_phase_deg": self.u_phase_deg,
                "displacement_m": self.displacement_m, "acceleration": self.acceleration, "fringes": self.fringes,
                "heydemann": self.heydemann.to_dict(), "residual": dict(self.residual),
                "budget": {k: dict(v) for k, v in self.budget.items()}, "slices": self.slices,
                "fringe_count": None if self.fringe_count is None else self.fringe_count.to_dict(),
                "warnings": list(self.warnings)}


def _amp_phase(fit, idx):
    return float(fit.amplitude[idx]), float(fit.phase[idx]), float(fit.u_amplitude[idx]), float(fit.u_phase[idx])


def _wrap(x):
    if isinstance(x, np.ndarray):
        # in place: the record-long arrays of the Heydemann projection are wrapped several times
        y = x + math.pi
        np.remainder(y, 2 * math.pi, out=y)
        y -= math.pi
        return y
    return (x + math.pi) % (2 * math.pi) - math.pi


def _largest_gap(ang: np.ndarray) -> float:
    """The widest empty arc between angles in [-pi, pi], on the circle, rad (2 pi for none).

    Sorting a million angles costs more than the rest of the check: 1024 bins tell first whether an arc wider
    than a quarter turn can be empty at all (it would leave 254 consecutive bins empty); only then are the
    angles sorted, so the answer is the sorted one whenever it matters.
    """
    if not ang.size:
        return 2 * math.pi
    nb = 1024
    idx = ((ang + math.pi) * (nb / (2 * math.pi))).astype(np.intp)
    np.clip(idx, 0, nb - 1, out=idx)
    full = np.bincount(idx, minlength=nb) > 0
    # longest circular run of empty bins; an empty arc spans at most it plus the two partly filled ends
    pos = np.flatnonzero(full)
    runs = np.diff(np.concatenate([pos, pos[:1] + nb])) - 1
    if (int(runs.max()) + 2) * (2 * math.pi / nb) <= math.pi / 2:
        return float((int(runs.max()) + 2) * (2 * math.pi / nb))  # an upper bound, below the quarter turn
    a = np.sort(ang)
    return float(np.max(np.diff(np.concatenate([a, a[:1] + 2 * math.pi]))))


def _quantile_above(v: np.ndarray, q: float, limit: float) -> bool:
    """``np.quantile(v, q) > limit`` (linear interpolation) from a count, partitioning only on a tie."""
    n = v.size
    h = (n - 1) * q
    j = int(math.floor(h))
    above = int(np.count_nonzero(v > limit))
    # the sorted v has v[j] > limit iff at least n - j values exceed it
    if above >= n - j:
        return True
    if above < n - j - 1 or j + 1 >= n:
        return False
    return bool(float(np.quantile(v, q)) > limit)


def _chi2_upper(dof: int, p: float = 0.99) -> float:
    from scipy.stats import chi2

    return float(chi2.ppf(p, dof))


def _model(fit, n: int, fs: float) -> np.ndarray:
    """The fitted sines, offsets and drifts of a batch fit, shape (channels, n)."""
    from senscal.sinefit._kernels import harmonic_basis

    w = 2 * math.pi * float(np.ravel(fit.frequency)[0])
    amp = np.atleast_2d(fit.harmonic_amplitudes)
    ph = np.atleast_2d(fit.harmonic_phases)
    # sin(k w t + ph) = sin(k w t) cos ph + cos(k w t) sin ph: the sine fit's own basis rows (re-anchored
    # rotation, compiled for long records) and one matrix product, not a trig evaluation per harmonic and
    # channel of a million samples (issue 28)
    coef = np.empty((amp.shape[0], 2 * amp.shape[1]))
    coef[:, 0::2] = amp * np.cos(ph)
    coef[:, 1::2] = amp * np.sin(ph)
    out = coef @ harmonic_basis(n, w / fs, 0.0, amp.shape[1])
    out += np.asarray(fit.offset, float).reshape(-1, 1)
    if fit.drift is not None:
        out += np.asarray(fit.drift, float).reshape(-1, 1) * (np.arange(n) / fs - fit.t_ref)
    return out


def _tone(r: np.ndarray, fs: float, freq: float):
    """(frequency, samples) of the largest tone in a residual when it is beyond chance, else None.

    The periodogram of noise over N/2 bins, each bin divided by the noise's mean at that frequency, exceeds
    ``T`` somewhere with probability ``N/2 exp(-T)``; p = 1e-3 keeps false detections rare. The mean is the
    local one (:func:`_local_level`): coloured noise (laser frequency noise, air turbulence) makes the
    spectrum red, and a global median then took the low-frequency bins for tones (three spurious sines
    removed per record, five times the white case's time, issue 28).
    """
    from senscal.errors import SenscalError
    from senscal.sinefit import fit_sine

    n = r.size
    spec = np.abs(np.fft.rfft(r - r.mean())) ** 2
    spec[0] = 0.0
    level, s_log = _local_level(spec)
    if level is None:
        return None
    ratio = spec / level
    ratio[0] = 0.0
    k = int(np.argmax(ratio))
    # the level is estimated (relative sd s_log): exp(-T (1 + e)) averaged over e ~ N(0, s_log) is
    # exp(-T + T^2 s_log^2 / 2), so T solves T - T^2 s_log^2 / 2 = ln(N/2 / p)
    big = math.log(0.5 * n / 1e-3)
    thr = big
    for _ in range(20):
        thr = big + 0.5 * thr * thr * s_log * s_log
    if ratio[k] < thr:
        return None
    f_k = k * fs / n
    if abs(f_k - freq) < 2 * fs / n or f_k < 2 * fs / n:
        return None  # at the excitation (inseparable) or a slow drift: left to the fit and the slices
    try:
        tf = fit_sine(r, fs=fs, harmonics=1, noise_model="white")
    except SenscalError:
        return None
    t = np.arange(n) / fs
    return float(tf.frequency), float(tf.amplitude) * np.sin(2 * math.pi * float(tf.frequency) * t + float(tf.phase))


TONE_BLOCK = 256  # periodogram bins per block of the local noise level


def _local_level(spec: np.ndarray):
    """Mean noise periodogram at every bin, robustly and locally; and the estimate's relative sd.

    Medians of blocks of :data:`TONE_BLOCK` bins (divided by ln 2: the median of an exponential variable
    is ln 2 times its mean; a tone is one bin of the block and moves the median little), interpolated
    linearly in log between the blocks' centres, so that a smooth spectrum's slope (1/f^2 above an AR(1)
    corner) is followed. A block's median of B exponential bins has relative sd ``1 / (ln 2 sqrt(B))``
    (9 % at B = 256). Records under two blocks use one median over all bins, as white noise allows.

    Returns
    -------
    (level, s_log)
        ``level`` shape of ``spec`` (None when the spectrum is zero); ``s_log`` the relative sd.
    """
    m = spec.size - 1
    nb = m // TONE_BLOCK
    if nb < 2:
        mean = float(np.median(spec[1:])) / math.log(2.0) if m > 0 else 0.0
        return (np.full(spec.size, mean) if mean > 0 else None), 1.0 / (math.log(2.0) * math.sqrt(max(m, 1)))
    # the last block takes the bins left over
    med = np.median(spec[1:1 + nb * TONE_BLOCK].reshape(nb, TONE_BLOCK), axis=1)
    if m > nb * TONE_BLOCK:
        med[-1] = np.median(spec[1 + (nb - 1) * TONE_BLOCK:])
    if not np.all(med > 0):
        return None, 0.0
    centres = 1 + TONE_BLOCK * np.arange(nb) + 0.5 * (TONE_BLOCK - 1)
    level = np.exp(np.interp(np.arange(spec.size), centres, np.log(med / math.log(2.0))))
    return level, 1.0 / (math.log(2.0) * math.sqrt(TONE_BLOCK))


def _intensity_normalised(x, y, hf: HeydemannFit, passes: int = 2, radius: np.ndarray | None = None):
    """The quadrature pair with a linear change of the laser intensity divided out, and its ellipse refitted.

    The conic fit assumes one radius; an intensity changing over the record (the laser's power, the beam
    walking on the detector) smears the ellipse, and the fitted offsets, gain and quadrature error then leave a
    phase error periodic in the fringe phase, repeated every vibration period: a bias of the fundamental
    (1.5e-5 of the sensitivity at 1 kHz for a 20 % change, noise-free) that no noise term holds. The corrected
    radius is fitted by a straight line in time; when its slope is beyond chance (3.29 u, the radius residual
    as the noise) both signals' alternating parts are divided by it about the offsets and the ellipse refitted.
    ``atan2`` reads the same angle from the scaled pair, so nothing downstream changes but the parameters.

    ``radius``, when given, is the corrected radius of ``hf`` on ``x, y`` (from :func:`_heydemann`).

    Returns
    -------
    (x, y, fit, trend)
        ``trend`` is the relative change of the radius over the record (0 when none was removed).
    """
    n = x.size
    tau = (np.arange(n) - 0.5 * (n - 1)) / max(n - 1, 1)  # -1/2 .. 1/2 over the record
    stt = float(tau @ tau)
    trend = 0.0
    r = radius
    for _ in range(passes):
        if r is None:
            c, s = _corrected(x, y, hf.params, hf.amplitude_i)
            r = np.sqrt(c * c + s * s)
        r0 = float(r.mean())
        b1 = float(tau @ (r - r0)) / stt
        res = r - r0 - b1 * tau
        u_b1 = math.sqrt(float(res @ res) / max(n - 2, 1) / stt)
        if not abs(b1) > 3.29 * u_b1 or abs(b1) < 1e-12:
            break
        scale = 1.0 + (b1 / r0) * tau
        x = hf.offset_i + (x - hf.offset_i) / scale
        y = hf.offset_q + (y - hf.offset_q) / scale
        trend = (1.0 + trend) * (1.0 + b1 / r0) - 1.0 if trend else b1 / r0
        hf, r = _heydemann(x, y)
    return x, y, hf, trend


def calibrate_point(i_sig, q_sig, output, fs: float, *, freq: float | None = None, wavelength_nm: float = 632.8,
                    harmonics: int = 3, drift: bool = True, slices: int = 10, u_wavelength_rel: float = 0.0,
                    u_gain_rel: float = 0.0, u_gain_phase_deg: float = 0.0, u_other_rel: float = 0.0,
                    u_other_phase_deg: float = 0.0, sign_check: bool = True) -> PrimaryPoint:
    """Sensitivity and phase of an accelerometer at one frequency (ISO 16063-11 method 3).

    Parameters
    ----------
    i_sig, q_sig : array_like, shape (N,)
        Quadrature outputs of the homodyne interferometer.
    output : array_like, shape (N,)
        Accelerometer output (its unit is the sensitivity's numerator).
    fs : float
        Sample rate, Hz (uniform sampling).
    freq : float, optional
        Excitation frequency, Hz; estimated from the displacement when omitted.
    wavelength_nm : float
        Laser wavelength in vacuum (or in air, as the user corrects it), nm.
    harmonics : int
        Harmonics fitted with the fundamental (exciter distortion).
    drift : bool
        Fit a linear drift of the offsets (output drift, slow table motion).
    slices : int
        Per-period (sliced) fits whose spread is the type A term for what the
        model lacks.
    u_wavelength_rel, u_gain_rel, u_other_rel : float
        Type B relative standard uncertainties: wavelength, gain of the
        output's voltage measurement, other (transverse motion, base strain ...).
    u_gain_phase_deg, u_other_phase_deg : float
        Type B phase standard uncertainties, deg.
    sign_check : bool
        Refuse a phase near 180 deg (I/Q swapped or an inverted output).

    Returns
    -------
    PrimaryPoint

    Raises
    ------
    DataError, InputError
        Not a quadrature pair, too few fringes, aliased fringes, I/Q swapped
        (one line with the fix).
    """
    from senscal.sinefit import fit_sine

    check_wavelength(wavelength_nm)
    x = np.asarray(i_sig, float)
    y = np.asarray(q_sig, float)
    out = np.asarray(output, float)
    if not (x.shape == y.shape == out.shape and x.ndim == 1):
        raise InputError("the I, Q and output channels must be one-dimensional and of equal length")
    if not np.all(np.isfinite(x)) or not np.all(np.isfinite(y)) or not np.all(np.isfinite(out)):
        raise DataError("NaN or inf in the interferometer or output samples: cut them out with --start/--stop")
    sx, sy = float(np.std(x)), float(np.std(y))
    if sx == 0.0 or sy == 0.0:  # a dead or unwired output: the pair check below needs two signals
        raise DataError(f"the {'I' if sx == 0.0 else 'Q'} channel is constant: a single channel is not a quadrature "
                        "pair; give both quadrature outputs with --quadrature I,Q")
    if sx > 0 and sy > 0:
        r = abs(float(np.mean((x - x.mean()) * (y - y.mean()))) / (sx * sy))
        if r > 0.995:
            raise DataError(f"the I and Q channels are one signal (correlation {r:.4f}): a single channel is not a "
                            "quadrature pair; give both quadrature outputs with --quadrature I,Q")
    # coverage of the ellipse before fitting it: a partial arc (under one fringe) has no unique ellipse
    ang = np.arctan2((y - 0.5 * (y.max() + y.min())) / max(np.ptp(y), 1e-300),
                     (x - 0.5 * (x.max() + x.min())) / max(np.ptp(x), 1e-300))
    gap = _largest_gap(ang)
    if gap > math.pi / 2:
        raise DataError(f"too few fringes: the quadrature signals leave {math.degrees(gap):.0f} deg of the ellipse "
                        "empty; the Heydemann fit needs at least one full fringe (raise the vibration amplitude)")
    hf, rad = _heydemann(x, y)
    x, y, hf, intensity_trend = _intensity_normalised(x, y, hf, radius=rad)
    del rad
    c_, s_ = _corrected(x, y, hf.params)
    phi_raw = np.arctan2(s_, c_)
    # the steps' whole turns: the unwrapped phase subtracts them (integers, summed exactly), and the wrapped
    # step is what remains
    dd = np.diff(phi_raw)
    turns = np.rint(dd * (0.5 / math.pi))
    step = dd - 2 * math.pi * turns
    np.abs(step, out=step)
    if step.size and _quantile_above(step, 0.999, 0.75 * math.pi):
        raise DataError("the fringes alias at this sample rate (phase steps near pi per sample): record faster or "
                        "lower the vibration amplitude")
    phi = phi_raw.copy()
    np.cumsum(turns, out=turns)
    turns *= 2 * math.pi
    phi[1:] -= turns
    del dd, turns, step
    fringes = float(np.ptp(phi) / (2 * math.pi))
    if fringes < 1.0:
        raise DataError(f"too few fringes ({fringes:.2f}): the Heydemann fit needs at least one full fringe "
                        "(raise the vibration amplitude)")
    lam = wavelength_nm * 1e-9
    # the displacement written straight into the two-row array the fits take (no stacked copy)
    both = np.empty((2, phi.size))
    disp = both[0]
    np.multiply(phi, lam, out=disp)
    disp /= 4 * math.pi
    both[1] = out
    n = disp.size
    if freq is None:
        f0 = fit_sine(disp, fs=fs, harmonics=1, drift=drift)
        freq = float(f0.frequency)
        u_f = float(f0.u_frequency)
    else:
        u_f = 0.0
    if not (freq > 0 and freq < fs / 2):
        raise InputError(f"--freq {freq:g} Hz must be positive and below the Nyquist frequency {fs / 2:g} Hz")
    fit = fit_sine(both, fs=fs, freq=freq, harmonics=harmonics, drift=drift)
    # tones that are no harmonic of the excitation (mains hum, a second exciter mode): found in the residual,
    # fitted by the same engine and removed, so that neither the fit's noise model nor the slices take them for noise
    tones: list[float] = []
    for _ in range(3):
        found = False
        model = _model(fit, n, fs)
        for row in range(2):
            tf = _tone(both[row] - model[row], fs, freq)
            if tf is not None:
                both[row] = both[row] - tf[1]
                tones.append(tf[0])
                found = True
        if not found:
            break
        fit = fit_sine(both, fs=fs, freq=freq, harmonics=harmonics, drift=drift)
    ad, pd, uad, upd = _amp_phase(fit, 0)
    ao, po, uao, upo = _amp_phase(fit, 1)
    w = 2 * math.pi * freq
    acc = w * w * ad
    sens = ao / acc
    phase = _wrap(po - (pd + math.pi))
    warnings: list[str] = list(fit.warnings)
    if sign_check and abs(phase) > math.pi / 2:
        raise DataError(f"the output is {math.degrees(phase):+.1f} deg from the acceleration: the displacement's "
                        "sign is flipped (I and Q swapped: give --quadrature Q,I), or the output is inverted "
                        "(then --no-sign-check)")
    # type A from the fits' covariances (laser noise, output noise; coloured noise by the engine's model)
    ud_rel, uo_rel = uad / ad, uao / ao
    u_fit_rel = math.hypot(ud_rel, uo_rel)
    u_fit_ph = math.hypot(upd, upo)
    # per-period (sliced) fits: the spread of the ratio over slices holds what the model lacks
    periods = n * freq / fs
    m = int(min(slices, math.floor(periods)))
    u_sl_rel = u_sl_ph = 0.0
    s_rel = s_ph = float("nan")
    if m >= 3:
        per = math.floor(periods / m)
        # whole periods where the sample rate allows; never more samples than the record holds
        L = min(int(round(per * fs / freq)), n // m)
        seg = both[:, : m * L].reshape(2, m, L)
        sf = fit_sine(seg.reshape(2 * m, L), fs=fs, freq=freq, harmonics=harmonics, drift=False,
                      noise_model="white")
        amp = np.asarray(sf.amplitude).reshape(2, m)
        ph = np.asarray(sf.phase).reshape(2, m)
        ratio = amp[1] / amp[0]
        dph = _wrap(ph[1] - ph[0] - phase - math.pi)
        s_rel = float(np.std(ratio, ddof=1) / np.mean(ratio) / math.sqrt(m))
        s_ph = float(np.std(dph, ddof=1) / math.sqrt(m))
        # the slices' spread replaces the fit's u only when it exceeds it beyond chance (chi-square, 1 %)
        lim = _chi2_upper(m - 1) / (m - 1)
        if s_rel ** 2 > lim * u_fit_rel ** 2:
            u_sl_rel = math.sqrt(s_rel ** 2 - u_fit_rel ** 2)
        if s_ph ** 2 > lim * u_fit_ph ** 2:
            u_sl_ph = math.sqrt(s_ph ** 2 - u_fit_ph ** 2)
        if u_sl_rel > 2 * u_fit_rel or u_sl_ph > 2 * u_fit_ph:
            warnings.append(named("unmodelled-components", f"the {m} per-period fits scatter "
                                  f"{s_rel / max(u_fit_rel, 1e-300):.1f}x (magnitude) and "
                                  f"{s_ph / max(u_fit_ph, 1e-300):.1f}x (phase) beyond the fit's noise "
                                  "(drift, hum or parasitic motion); their spread is in u"))
    # Heydemann parameters' u propagated to magnitude and phase: the phase change a parameter step makes,
    # projected on the fundamental (a linear change of the fit, so no re-fit is needed)
    J = np.zeros((2, 4))
    from senscal.sinefit._kernels import harmonic_basis

    sn, cs = harmonic_basis(n, w / fs, pd, 1)  # sin, cos of w t + pd (the fit engine's rotation)
    g_ss, g_cc, g_sc = float(sn @ sn), float(cs @ cs), float(sn @ cs)
    det = g_ss * g_cc - g_sc * g_sc
    # d phi / d(p, q, g, alpha) in closed form, phi = atan2(s, c) with c = x - p and
    # s = ((y - q) / g - c sin alpha) / cos alpha: d phi = (c ds - s dc) / (c^2 + s^2); one pass over the record
    # instead of a corrected pair, an arctan2 and a wrap per parameter (a million samples at 1 MS/s)
    p_, q_, g_, al = hf.params
    ta, ca = math.tan(al), math.cos(al)
    # c_, s_: the corrected pair the phase was read from
    r2 = c_ * c_ + s_ * s_
    cr = c_ / r2
    dphi = np.empty((4, n))
    dphi[0] = cr * ta + s_ / r2
    dphi[1] = cr * (-1.0 / (g_ * ca))
    dphi[2] = cr * (y - q_) * (-1.0 / (g_ * g_ * ca))
    dphi[3] = cr * (s_ * ta - c_)
    dphi *= lam / (4 * math.pi)
    b_s, b_c = dphi @ sn, dphi @ cs
    # d = A sin(wt + pd) + dA sin(...) + A dp cos(...): solve the 2x2 normal equations, per parameter
    J[0] = (g_cc * b_s - g_sc * b_c) / det / ad
    J[1] = (g_ss * b_c - g_sc * b_s) / det / ad
    ch = J @ hf.covariance @ J.T
    u_hey_rel = math.sqrt(max(ch[0, 0], 0.0))
    u_hey_ph = math.sqrt(max(ch[1, 1], 0.0))
    deg = math.degrees
    budget = {
        "displacement_fit": {"type": "A", "u_rel": ud_rel, "u_phase_deg": deg(upd)},
        "output_fit": {"type": "A", "u_rel": uo_rel, "u_phase_deg": deg(upo)},
        "unmodelled_slices": {"type": "A", "u_rel": u_sl_rel, "u_phase_deg": deg(u_sl_ph)},
        "heydemann": {"type": "A", "u_rel": u_hey_rel, "u_phase_deg": deg(u_hey_ph)},
        "frequency": {"type": "A", "u_rel": 2 * u_f / freq, "u_phase_deg": 0.0},
        "wavelength": {"type": "B", "u_rel": float(u_wavelength_rel), "u_phase_deg": 0.0},
        "output_gain": {"type": "B", "u_rel": float(u_gain_rel), "u_phase_deg": float(u_gain_phase_deg)},
        "other": {"type": "B", "u_rel": float(u_other_rel), "u_phase_deg": float(u_other_phase_deg)},
    }
    u_rel = math.sqrt(sum(v["u_rel"] ** 2 for v in budget.values()))
    u_ph = math.sqrt(sum(v["u_phase_deg"] ** 2 for v in budget.values()))
    residual = {"displacement_rms_m": float(np.asarray(fit.residual_rms)[0]),
                "output_rms": float(np.asarray(fit.residual_rms)[1]), "ellipse_radius_rms": hf.radius_rms,
                "removed_tones_hz": tones,
                "intensity_trend_rel": intensity_trend, "slices_u_rel": s_rel, "slices_u_phase_deg": deg(s_ph) if s_ph == s_ph else s_ph}
    fc = None
    if n * freq / fs >= 1.0:
        # hysteresis a few noise sigmas: the ellipse's radius residual is the signals' noise relative to a, the
        # displacement's residual in fringe phase (rad) holds the beam's own noise as well (laser frequency noise,
        # air), which the radius does not see and which made extra crossings at the turning points (issue 28)
        sig_ph = float(np.asarray(fit.residual_rms)[0]) * 4 * math.pi / lam
        d_fc, u_d_fc, n_fc, m_fc = fringe_count(x, fs, freq, wavelength_nm, offset=hf.offset_i,
                                                amplitude=hf.amplitude_i,
                                                hysteresis=min(max(6.0 * max(hf.radius_rms, sig_ph), 0.005), 0.5))
        if d_fc > 0:
            s_fc = ao / (w * w * d_fc)
            u_s_fc = abs(s_fc) * math.hypot(u_d_fc / d_fc, uao / ao)
            applies = u_d_fc / d_fc <= FRINGE_RESOLUTION
            diff = sens / s_fc - 1.0
            fc = FringeCount(displacement_m=d_fc, u_displacement_m=u_d_fc, crossings=n_fc, periods=m_fc,
                             sensitivity=s_fc, u_sensitivity=u_s_fc, difference_rel=diff, applies=applies)
            # the two methods share the output's fit: their difference is the displacements' difference
            u_diff = math.hypot(u_d_fc / d_fc, ud_rel, u_hey_rel)
            if applies and abs(diff) > 2.0 * u_diff:
                warnings.append(named("fringe-count-mismatch", f"fringe counting gives a displacement "
                                      f"{-diff:+.2%} off the sine approximation's ({abs(diff) / u_diff:.1f} u): "
                                      "the motion is not a pure sine (exciter distortion counts in the fringes, "
                                      "not in the fundamental) or the fringes are miscounted"))
    return PrimaryPoint(frequency_hz=float(freq), sensitivity=float(sens), u_sensitivity=float(sens * u_rel),
                        phase_deg=deg(phase), u_phase_deg=u_ph, displacement_m=ad, acceleration=acc,
                        fringes=fringes, heydemann=hf, budget=budget, residual=residual, slices=max(m, 0),
                        fringe_count=fc, warnings=tuple(dict.fromkeys(warnings)))
