"""Least-squares sine fitting: three-parameter, four-parameter, multi-harmonic.

Model (time ``t`` exactly as given, phase in radians)::

    y = A sin(2 pi f t + phi) + C  [+ sum_k A_k sin(2 pi k f t + phi_k)]  [+ D (t - t_ref)]

References
----------
.. [1] IEEE Std 1057-2017, Standard for Digitizing Waveform Recorders, 4.1
   (three- and four-parameter sine fit).
.. [2] Yang et al., "Sinusoidal excitation calibration with a least-squares
   sine fit with offset", Transducer and Microsystem Technologies, 2014
   (seed 000; ``shared/METHODS.md`` section 1a).
.. [3] Qin Chaojun, "Three-parameter cosine fit in double-centrifuge dynamic
   calibration of linear accelerometers" (seed 003; METHODS.md section 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import ConvergenceError, DataError, InputError, TooFewSamplesError

__all__ = ["SineFit", "fit_sine", "wrap_phase"]

TWO_PI = 2.0 * math.pi


def wrap_phase(phase):
    """Wrap angles in radians to the interval (-pi, pi]."""
    out = np.pi - np.mod(np.pi - np.asarray(phase, dtype=float), TWO_PI)
    return out if np.ndim(out) else float(out)


@dataclass(frozen=True)
class SineFit(ResultMixin):
    """Result of :func:`fit_sine` for one channel or a batch of channels.

    Every quantity has the batch shape ``y.shape[:-1]`` (a scalar for one
    channel).  Uncertainties are standard uncertainties (k=1) from the
    residual variance with ``N - p`` degrees of freedom, propagated through
    the full parameter covariance.

    Attributes
    ----------
    frequency : float or ndarray
        Fundamental frequency in Hz (given or estimated).
    amplitude : float or ndarray
        Peak amplitude of the fundamental, in the unit of ``y``.
    phase : float or ndarray
        Phase of the fundamental at ``t = 0`` in radians, in (-pi, pi].
    offset : float or ndarray
        Constant term in the unit of ``y`` (at ``t_ref`` when drift is fitted).
    u_frequency, u_amplitude, u_phase, u_offset : float or ndarray
        Standard uncertainties (0 for a given frequency).
    covariance : ndarray
        Covariance of ``parameter_names``, shape (..., p, p).
    parameter_names : tuple of str
        Order of the covariance: amplitude, phase, offset, [drift],
        [frequency], then ``amplitude_k``, ``phase_k`` for k = 2..K.
    harmonic_amplitudes, harmonic_phases : ndarray
        Shape (..., K): amplitude and phase (rad, at t = 0) of harmonic k=1..K.
    u_harmonic_amplitudes, u_harmonic_phases : ndarray
        Their standard uncertainties.
    thd : float, ndarray or None
        Total harmonic distortion ``sqrt(sum_{k>=2} A_k^2) / A_1`` (ratio),
        None when only the fundamental was fitted.
    drift, u_drift : float, ndarray or None
        Linear drift of the offset in unit/s, None unless requested.
    t_ref : float
        Time (s) at which ``offset`` holds when drift is fitted (record centre).
    residual_rms : float or ndarray
        RMS of the residuals (weighted RMS with weights).
    snr_db : float or ndarray
        ``10 log10((A^2 / 2) / residual_rms^2)``.
    n_samples, dof : int
        Samples used and degrees of freedom ``N - p``.
    converged : bool or ndarray
        False only if the frequency iteration hit its limit.
    iterations : int or ndarray
        Gauss-Newton iterations (0 for a known frequency).
    frequency_estimated : bool
        True when the frequency was estimated.
    phase_centre, u_phase_centre : float or ndarray
        Phase of the fundamental (rad, in (-pi, pi]) at ``t_ref``, the
        record's centre time, and its standard uncertainty.  With an
        estimated frequency the phase at ``t = 0`` carries the frequency's
        uncertainty times the lever arm ``2 pi t_ref``; the centre phase does
        not, so it is the one to quote when ``t_ref`` is far from 0.
    noise_model : str or ndarray of str
        ``"white"``: uncertainties from the residual variance (the residual
        passed the whiteness and constant-variance tests, or was not tested).
        ``"coloured"``: the residual was correlated, so the uncertainties come
        from its autoregressive noise spectrum at the fitted frequency (and
        the model's level near 0 Hz for the offset and drift), propagated
        through the design matrix.  ``"phase-dependent"``: the residual
        variance follows the fitted phase (sample-clock/aperture jitter), so
        the uncertainties come from the heteroscedasticity-consistent
        (sandwich) covariance with the fitted variance of each sample, and
        the amplitudes are corrected for the jitter's shrinkage.
    dof_effective : float or ndarray
        Effective degrees of freedom of the uncertainties (``dof`` for white
        noise; from the variance of the noise-spectrum estimate otherwise).
    residual_lag1 : float or ndarray
        Lag-one autocorrelation of the residuals (dimensionless; NaN for a
        zero residual).  ``|r1| sqrt(N) > 2.58`` and ``|r1| > 0.01`` is the
        whiteness test's rejection (see :mod:`senscal.sinefit.noise`).
    variance_phase_stat : float or ndarray
        Koenker's ``N R^2`` of the squared residual regressed on ``cos 2
        theta`` and ``sin 2 theta`` (chi-square, 2 dof, for constant
        variance; NaN when not tested: weights, or coloured noise).
    jitter_rms : float or ndarray
        RMS timing jitter (s) estimated from the phase-dependent variance
        (NaN unless ``noise_model`` is ``"phase-dependent"``).
    lowfreq_chi2 : float or ndarray
        Chi-square of the residual's block means against ``u(offset)`` (see
        :func:`senscal.sinefit.variance.low_frequency_test`; NaN untested).
    lowfreq_dof : int
        Its degrees of freedom (0 when untested).
    warnings : tuple of str
        Named warnings (``coloured-noise``, ``heteroscedastic-noise``,
        ``low-frequency-noise``, ``phase-origin-far``) that say what departs
        from the fit's assumptions and what to do.
    """

    frequency: Any
    amplitude: Any
    phase: Any
    offset: Any
    u_frequency: Any
    u_amplitude: Any
    u_phase: Any
    u_offset: Any
    covariance: np.ndarray
    parameter_names: tuple[str, ...]
    harmonic_amplitudes: np.ndarray
    harmonic_phases: np.ndarray
    u_harmonic_amplitudes: np.ndarray
    u_harmonic_phases: np.ndarray
    thd: Any
    drift: Any
    u_drift: Any
    t_ref: float
    residual_rms: Any
    snr_db: Any
    n_samples: int
    dof: int
    converged: Any
    iterations: Any
    frequency_estimated: bool
    phase_centre: Any = None
    u_phase_centre: Any = None
    noise_model: Any = "white"
    dof_effective: Any = None
    residual_lag1: Any = float("nan")
    variance_phase_stat: Any = float("nan")
    jitter_rms: Any = float("nan")
    lowfreq_chi2: Any = float("nan")
    lowfreq_dof: int = 0
    warnings: tuple[str, ...] = ()

    @property
    def shape(self) -> tuple[int, ...]:
        """Batch shape (``()`` for one channel)."""
        return np.shape(self.amplitude)

    @property
    def harmonics(self) -> int:
        """Number of harmonics fitted (1 = fundamental only)."""
        return int(np.shape(self.harmonic_amplitudes)[-1])

    @property
    def angular_frequency(self):
        """``2 pi f`` in rad/s."""
        return TWO_PI * np.asarray(self.frequency) if np.ndim(self.frequency) else TWO_PI * float(self.frequency)

    def channel(self, index) -> "SineFit":
        """The result of one channel of a batch (``index`` into the batch shape)."""
        if not self.shape:
            raise InputError("this result holds a single channel; there is nothing to index")

        def pick(v):
            if v is None or isinstance(v, (str, tuple, bool)) or np.ndim(v) == 0:
                return v
            x = np.asarray(v)[index]
            # Object arrays (noise_model) give back plain str on indexing.
            return (x.item() if hasattr(x, "item") else x) if np.ndim(x) == 0 else x

        kw = {}
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            kw[name] = v if name in ("parameter_names", "t_ref", "n_samples", "dof", "frequency_estimated",
                                     "warnings", "lowfreq_dof") else pick(v)
        kw["warnings"] = fit_warnings(kw["noise_model"], kw["residual_lag1"], kw["dof_effective"], kw["u_phase"],
                                      self.t_ref, self.n_samples, self.frequency_estimated,
                                      variance_phase_stat=kw["variance_phase_stat"], jitter_rms=kw["jitter_rms"],
                                      lowfreq_chi2=kw["lowfreq_chi2"], lowfreq_dof=self.lowfreq_dof,
                                      drift=self.drift is not None)
        return SineFit(**kw)

    def evaluate(self, t) -> np.ndarray:
        """Model values at times ``t`` (s), shape ``batch + t.shape``."""
        t = np.asarray(t, dtype=float)
        w = np.asarray(self.angular_frequency)[..., None]
        amps = np.asarray(self.harmonic_amplitudes)
        phs = np.asarray(self.harmonic_phases)
        out = np.asarray(self.offset, dtype=float)[..., None] + np.zeros(t.shape)
        for k in range(amps.shape[-1]):
            out = out + amps[..., k, None] * np.sin((k + 1) * w * t + phs[..., k, None])
        if self.drift is not None:
            out = out + np.asarray(self.drift)[..., None] * (t - self.t_ref)
        return out if out.shape[:-1] else out.reshape(t.shape)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict; phases also given in degrees."""
        d = {k: to_jsonable(getattr(self, k)) for k in self.__dataclass_fields__}
        d["phase_deg"] = to_jsonable(np.degrees(self.phase))
        d["u_phase_deg"] = to_jsonable(np.degrees(self.u_phase))
        if self.phase_centre is not None:
            d["phase_centre_deg"] = to_jsonable(np.degrees(self.phase_centre))
            d["u_phase_centre_deg"] = to_jsonable(np.degrees(self.u_phase_centre))
        return d


# The phase at t = 0 of an estimated frequency is useless beyond one radian.
PHASE_U_LIMIT = 1.0


def fit_warnings(noise_model, residual_lag1, dof_effective, u_phase, t_ref: float, n_samples: int,
                 frequency_estimated: bool, *, variance_phase_stat=float("nan"), jitter_rms=float("nan"),
                 lowfreq_chi2=float("nan"), lowfreq_dof: int = 0, drift: bool = False) -> tuple[str, ...]:
    """Named warnings of a fit (one channel or a batch) from its per-channel fields.

    Parameters
    ----------
    noise_model, residual_lag1, dof_effective, u_phase : scalar or ndarray
        The fields of :class:`SineFit` (u_phase in rad).
    t_ref : float
        Record centre (s).
    n_samples : int
    frequency_estimated : bool
    variance_phase_stat, jitter_rms, lowfreq_chi2 : scalar or ndarray
        The fields of :class:`SineFit`.
    lowfreq_dof : int
    drift : bool
        Whether a drift was fitted (its u is in the low-frequency warning too).

    Returns
    -------
    tuple of str
    """
    from senscal.diagnostics import named
    from senscal.sinefit.noise import WHITE_R1_MIN, WHITE_Z, lag1_significant

    model = np.atleast_1d(np.asarray(noise_model))
    r1 = np.atleast_1d(np.asarray(residual_lag1, dtype=float))
    nu = np.atleast_1d(np.asarray(dof_effective if dof_effective is not None else np.nan, dtype=float))
    nu = np.broadcast_to(nu, r1.shape)
    up = np.atleast_1d(np.asarray(u_phase, dtype=float))
    batch = np.ndim(residual_lag1) > 0

    def which(mask):
        idx = np.flatnonzero(mask)
        if not batch:
            return ""
        shown = ", ".join(str(i) for i in idx[:8]) + (", ..." if idx.size > 8 else "")
        return f"channel{'s' if idx.size > 1 else ''} {shown} ({idx.size} of {mask.size}): "

    out = []
    bad = lag1_significant(r1, n_samples)
    lim = max(WHITE_Z / math.sqrt(n_samples), WHITE_R1_MIN)
    sw = bad & (model == "coloured")
    if sw.any():
        j = np.flatnonzero(sw)[np.argmax(np.abs(r1[sw]))]
        out.append(named("coloured-noise", (
            f"{which(sw)}the fit residual is correlated (lag-1 autocorrelation {r1[j]:.2f}, white-noise limit "
            f"+/-{lim:.2g}); u(amplitude), u(phase) and u(frequency) use the residual's noise spectrum at the "
            f"fitted frequency instead of its total variance, and u(offset){'/u(drift)' if drift else ''} an "
            f"autoregressive model's level near 0 Hz, which holds only while the noise is flat below about 1/T "
            f"(1/f noise and wander are not in it: see low-frequency-noise) ({nu[j]:.0f} effective degrees of "
            f"freedom: for 95 % use Student t, not k=2, when that is small); check for interference or drift, or "
            f"average longer records")))
    st = bad & (model == "white")
    if st.any():
        j = np.flatnonzero(st)[np.argmax(np.abs(r1[st]))]
        out.append(named("coloured-noise", (
            f"{which(st)}the fit residual is correlated (lag-1 autocorrelation {r1[j]:.2f}, white-noise limit "
            f"+/-{lim:.2g}) but the uncertainties assume white noise (time base not uniform, or noise_model='white' "
            f"was forced), so they can be several times too small; resample to a uniform time base")))
    from scipy.stats import chi2 as _chi2

    from senscal.sinefit.variance import VARIANCE_ALPHA

    hs = np.broadcast_to(np.atleast_1d(np.asarray(variance_phase_stat, dtype=float)), r1.shape)
    het = np.nan_to_num(hs, nan=0.0) > _chi2.isf(VARIANCE_ALPHA, 2)
    if het.any():
        jr = np.broadcast_to(np.atleast_1d(np.asarray(jitter_rms, dtype=float)), r1.shape)
        j = np.flatnonzero(het)[np.argmax(hs[het])]
        switched = model[j] == "phase-dependent"
        jt = (f"; it is what a sample-clock or aperture jitter of about {jr[j]:.2g} s rms does, and the amplitude "
              f"was corrected for the shrinkage exp(-w^2 jitter^2 / 2) that jitter causes") if np.isfinite(jr[j]) else ""
        out.append(named("heteroscedastic-noise", (
            f"{which(het)}the residual variance follows the phase of the fitted sine (test statistic {hs[j]:.3g}, "
            f"1 % limit {_chi2.isf(VARIANCE_ALPHA, 2):.3g})" + (
                f": the uncertainties use the heteroscedasticity-consistent (sandwich) covariance with each "
                f"sample's fitted variance{jt}; check the sample clock" if switched else
                ": but the uncertainties assume one variance for all samples (noise_model was forced), so "
                "u(phase) and u(frequency) can be too small; use noise_model='auto'"))))
    if lowfreq_dof:
        ls = np.broadcast_to(np.atleast_1d(np.asarray(lowfreq_chi2, dtype=float)), r1.shape)
        lim_lf = _chi2.isf(VARIANCE_ALPHA, lowfreq_dof)
        lf = np.nan_to_num(ls, nan=0.0) > lim_lf
        if lf.any():
            j = np.flatnonzero(lf)[np.argmax(ls[lf])]
            out.append(named("low-frequency-noise", (
                f"{which(lf)}the residual's {lowfreq_dof // 2} lowest frequencies (below {lowfreq_dof // 2}/T) hold "
                f"{ls[j] / lowfreq_dof:.3g} times the noise that u(offset) assumes (chi-square {ls[j]:.3g} with "
                f"{lowfreq_dof} dof, "
                f"1 % limit {lim_lf:.3g}): the noise grows below 1/T (1/f noise, wander or drift), which no "
                f"noise model of the fit includes, so u(offset){'/u(drift)' if drift else ''} does not cover and "
                f"can be several times too small; quote the offset with a type B component from a longer record "
                f"or an Allan deviation, or fit with drift")))
    if frequency_estimated:
        far = up > PHASE_U_LIMIT
        if far.any():
            j = np.flatnonzero(far)[np.argmax(up[far])]
            out.append(named("phase-origin-far", (
                f"{which(far)}u(phase at t=0) = {up[j]:.3g} rad: the phase is extrapolated from the record "
                f"(centre t = {t_ref:.6g} s) to t = 0 with the estimated frequency's uncertainty, so it is "
                f"meaningless; quote the phase at the record centre (phase_centre)")))
    return tuple(out)


# ---------------------------------------------------------------------------
# Input checking
# ---------------------------------------------------------------------------

def _time_base(n: int, t, fs) -> tuple[np.ndarray | None, float, float, float, bool]:
    """Return (t or None, t_mid, dt, first, uniform)."""
    if t is not None and fs is not None:
        raise InputError("give either t (time stamps, s) or fs (sample rate, Hz), not both")
    if t is None and fs is None:
        raise InputError("give the time stamps t (s) or the sample rate fs (Hz)")
    if t is None:
        fs = float(fs)
        if not math.isfinite(fs) or fs <= 0:
            raise InputError(f"sample rate fs must be a positive number of Hz, got {fs!r}")
        dt = 1.0 / fs
        return None, 0.5 * (n - 1) * dt, dt, 0.0, True
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size != n:
        raise InputError(f"t must be 1-D with one time stamp per sample ({n}), got shape {t.shape}")
    from senscal.io.recording import check_time

    check_time(t)
    d = np.diff(t)
    dt_mean = (t[-1] - t[0]) / (n - 1) if n > 1 else 1.0
    uniform = bool(np.ptp(d) <= 1e-6 * dt_mean + 4e-16 * np.max(np.abs(t))) if n > 2 else True
    return t, 0.5 * (t[0] + t[-1]), dt_mean, float(t[0]), uniform


def _check_y(y, full: bool = True) -> np.ndarray:
    y = np.asarray(y, dtype=np.float64)
    if y.ndim == 0:
        raise InputError("y must hold samples along its last axis")
    if not full:
        return y
    bad = ~np.isfinite(y)
    if bad.any():
        idx = np.argwhere(bad)[0]
        ch = tuple(int(i) for i in idx[:-1])
        where = f"channel {ch if len(ch) > 1 else ch[0]} " if ch else ""
        raise DataError(f"{where}has NaN or inf in data row {int(idx[-1]) + 1}; remove or interpolate bad samples before fitting")
    _check_magnitude(y)
    return y


# Squares and sums of squares of larger values overflow float64 inside the solver.
_MAX_ABS = 1e150


def _check_magnitude(y: np.ndarray) -> None:
    peak = float(np.max(np.abs(y))) if y.size else 0.0
    if peak > _MAX_ABS:
        raise DataError(f"values up to {peak:.3g} are too large for a least-squares fit (their squares overflow); "
                        f"rescale the data, e.g. express it in a larger unit")


# ---------------------------------------------------------------------------
# Linear part: fixed frequency
# ---------------------------------------------------------------------------

def _design(tau: np.ndarray, w: float, harmonics: int, drift: bool) -> np.ndarray:
    cols = []
    for k in range(1, harmonics + 1):
        cols.append(np.sin(k * w * tau))
        cols.append(np.cos(k * w * tau))
    cols.append(np.ones_like(tau))
    if drift:
        cols.append(tau)
    return np.stack(cols, axis=1)


def _lstsq_many(a: np.ndarray, y2: np.ndarray, sw: np.ndarray | None):
    """Weighted LS for many right-hand sides: coefs (C, p), rss (C,), inv normal matrix (p, p).

    The normal matrix, scaled to unit diagonal, is Cholesky-factored when it
    is well conditioned (the centred sin/cos/1 basis nearly always is): one
    pass over the data instead of an SVD of the N x p matrix.  Residuals are
    then computed explicitly, so no precision is lost in the residual
    variance.  Ill-conditioned problems fall back to the SVD.
    """
    aw = a if sw is None else a * sw[:, None]
    # Channels stay rows (contiguous) throughout: (C, N) products are fast.
    yw = y2 if sw is None else y2 * sw[None, :]
    gram = aw.T @ aw
    d = np.sqrt(np.diag(gram))
    if np.all(d > 0):
        gs = gram / d[:, None] / d[None, :]
        ev = np.linalg.eigvalsh(gs)
        if ev[0] > ev[-1] * 1e-10:
            cho = scipy.linalg.cho_factor(gs)
            coef = (scipy.linalg.cho_solve(cho, (yw @ aw).T / d[:, None]) / d[:, None]).T
            resid = yw - coef @ aw.T
            rss = np.einsum("ij,ij->i", resid, resid)
            ginv = scipy.linalg.cho_solve(cho, np.eye(gs.shape[0])) / d[:, None] / d[None, :]
            return coef, rss, ginv
    u, s, vt = np.linalg.svd(aw, full_matrices=False)
    _check_rank(s)
    coef = ((vt.T / s) @ (u.T @ yw.T)).T
    resid = yw - coef @ aw.T
    rss = np.einsum("ij,ij->i", resid, resid)
    ginv = (vt.T / s**2) @ vt
    return coef, rss, ginv


def _check_rank(s: np.ndarray) -> None:
    # Beyond a condition number of 1e8 the parameters lose half their digits.
    if not s[-1] > s[0] * 1e-8:
        raise DataError(
            "the record is too short (or the frequency too low) to tell the sine from the offset/drift: "
            "the fit matrix is singular; record at least one full period"
        )


def _design_rows(n: int, dt: float, tau0: float, w: float, harmonics: int, drift: bool) -> np.ndarray:
    """The uniform fit's design as rows, shape (2K + 1 + drift, n): sin and cos of each harmonic (the
    compiled rotation), the constant, and with ``drift`` the centred time ``tau0 + i dt`` [s]."""
    from senscal.sinefit import _kernels as kern

    nb_ = 2 * harmonics
    rows = np.empty((nb_ + 1 + int(drift), n))
    kern.harmonic_basis(n, w * dt, w * tau0, harmonics, out=rows)
    rows[nb_] = 1.0
    if drift:
        np.multiply(np.arange(n), dt, out=rows[nb_ + 1])
        rows[nb_ + 1] += tau0
    return rows


def _fast_uniform(y2: np.ndarray, n: int, dt: float, tau0: float, w: float, harmonics: int, drift: bool):
    """Known frequency, uniform time, no weights: the one-pass path (compiled for large records)."""
    from senscal.sinefit import _kernels as kern

    p = 2 * harmonics + 1 + int(drift)
    nb_ = 2 * harmonics
    rotated = harmonics == 1 and not drift
    rows = None
    if rotated:
        # Fundamental + offset: the basis is generated inside the pass.
        tau = np.empty(0)
        basis = None
        gram = kern.gram_rotated(n, w * dt, w * tau0)
    else:
        # The design's rows (basis, constant, centred time) in one array, returned for the residual tests.
        rows = _design_rows(n, dt, tau0, w, harmonics, drift)
        basis = rows[:nb_]
        tau = rows[nb_ + 1] if drift else np.empty(0)
        gram = np.empty((p, p))
        gram[:nb_, :nb_] = basis @ basis.T
        gram[:nb_, nb_] = gram[nb_, :nb_] = basis.sum(axis=1)
        gram[nb_, nb_] = n
        if drift:
            gram[:nb_, nb_ + 1] = gram[nb_ + 1, :nb_] = basis @ tau
            gram[nb_, nb_ + 1] = gram[nb_ + 1, nb_] = tau.sum()
            gram[nb_ + 1, nb_ + 1] = tau @ tau
    # Scale to unit diagonal so the condition number means something.
    sc = 1.0 / np.sqrt(np.diag(gram))
    gs = gram * sc[:, None] * sc[None, :]
    ev = np.linalg.eigvalsh(gs)
    _check_rank(np.sqrt(np.maximum(ev[::-1], 0.0)))
    try:
        cho = scipy.linalg.cho_factor(gs)
    except np.linalg.LinAlgError:
        _check_rank(np.array([1.0, 0.0]))
    pilot = y2[:, 0].copy()
    yc = np.ascontiguousarray(y2)
    big = yc.size >= kern.PARALLEL_MIN_SAMPLES and yc.shape[0] > 1
    if rotated:
        aty, yy, l1v = (kern.project_rotated if big else kern.project_rotated_serial)(yc, w * dt, w * tau0, pilot)
    else:
        proj = kern.project_parallel if big else kern.project_serial
        aty, yy, l1v = proj(yc, basis, tau, drift, pilot, kern.num_threads() if big else 1)
    if not (np.all(np.isfinite(aty)) and np.all(np.isfinite(yy))):
        # NaN/inf poisons the sums: locate it for the message.
        _check_y(y2, full=True)
    coef = scipy.linalg.cho_solve(cho, (aty * sc).T).T * sc
    rss = yy - np.einsum("ij,ij->i", coef, aty)
    lag1 = _residual_lag1(coef, aty, l1v, gram, yc[:, -1] - pilot, n, dt, tau0, w, harmonics, drift)
    # Cancellation guard: where the residual is a tiny fraction of the signal
    # energy, recompute it exactly in a second pass.
    coef[:, 2 * harmonics] += pilot
    redo = np.flatnonzero(rss < 1e-9 * np.maximum(yy, 1e-300))
    if redo.size:
        if basis is None:
            basis = kern.harmonic_basis(n, w * dt, w * tau0, harmonics)
        rss[redo], lag1[redo] = kern.residual_ss(yc, basis, tau, drift, coef, redo)
    rss = np.maximum(rss, 0.0)
    ginv = scipy.linalg.cho_solve(cho, np.eye(p)) * sc[:, None] * sc[None, :]
    return coef, rss, ginv, lag1, rows


def _basis_at(tau_i: float, w: float, harmonics: int, drift: bool) -> np.ndarray:
    """One row of the design matrix at centred time ``tau_i`` (s)."""
    row = []
    for k in range(1, harmonics + 1):
        row += [math.sin(k * w * tau_i), math.cos(k * w * tau_i)]
    row.append(1.0)
    if drift:
        row.append(tau_i)
    return np.array(row)


def _shift(w: float, dt: float, harmonics: int, drift: bool, sign: float) -> np.ndarray:
    """Matrix M with ``a(tau - sign dt) = M a(tau)`` for a design row ``a``."""
    p = 2 * harmonics + 1 + int(drift)
    m = np.eye(p)
    for k in range(1, harmonics + 1):
        c, s = math.cos(k * w * dt), sign * math.sin(k * w * dt)
        i = 2 * k - 2
        m[i, i], m[i, i + 1], m[i + 1, i], m[i + 1, i + 1] = c, -s, s, c
    if drift:
        m[p - 1, p - 2] = -sign * dt
    return m


def _residual_lag1(coef, aty, l1v, gram, vlast, n, dt, tau0, w, harmonics, drift):
    """``sum_i r_i r_{i-1}`` of the residuals from the one-pass sums, per channel.

    With ``v = y - pilot`` (so ``v_0 = 0``), model ``m_i = c . a_i`` and a
    design row one sample earlier ``a_{i-1} = M a_i``::

        sum r_i r_{i-1} = sum v_i v_{i-1} - (M^T c).P - (M^-T c).P + v_{N-1} (M^-T c).a_{N-1}
                          + c' G M^T c - m_0 (M^T c).a_0

    where ``P = A^T v`` and ``G = A^T A``: no second pass over the data.
    """
    mt = _shift(w, dt, harmonics, drift, 1.0)
    mi = _shift(w, dt, harmonics, drift, -1.0)
    a0 = _basis_at(tau0, w, harmonics, drift)
    al = _basis_at(tau0 + (n - 1) * dt, w, harmonics, drift)
    cm = coef @ mt
    cp = coef @ mi
    return (l1v - np.einsum("ij,ij->i", cm, aty) - np.einsum("ij,ij->i", cp, aty) + vlast * (cp @ al)
            + np.einsum("ij,jk,ik->i", coef, gram, cm) - (coef @ a0) * (cm @ a0))


# ---------------------------------------------------------------------------
# Frequency estimation
# ---------------------------------------------------------------------------

def _initial_frequency(yc: np.ndarray, t: np.ndarray | None, dt: float, first: float) -> float:
    """Interpolated-DFT estimate (Hann window, three-bin interpolation), in Hz."""
    n = yc.size
    if t is not None:
        grid = first + np.arange(n) * dt
        yc = np.interp(grid, t, yc)
    yc = yc - yc.mean()
    win = np.hanning(n)
    spec = np.abs(np.fft.rfft(yc * win))
    spec[0] = 0.0
    k = int(np.argmax(spec))
    if k == 0 or spec[k] == 0.0:
        raise ConvergenceError("no sinusoid found in the record (flat spectrum); check the channel or give --freq")
    if 1 <= k < spec.size - 1:
        a, b, c = spec[k - 1], spec[k], spec[k + 1]
        delta = 2.0 * (c - a) / (a + 2.0 * b + c)
    else:
        delta = 0.0
    return (k + delta) / (n * dt)


def _fit_unknown(y1: np.ndarray, tau: np.ndarray, sw: np.ndarray | None, f0: float, harmonics: int,
                 drift: bool, max_iter: int):
    """Four-parameter (IEEE 1057) Gauss-Newton fit with step halving."""
    w = TWO_PI * f0

    def linear(wv):
        a = _design(tau, wv, harmonics, drift)
        coef, rss, _ = _lstsq_many(a, y1[None, :], sw)
        return coef[0], rss[0]

    coef, rss = linear(w)
    converged = False
    it = 0
    span = tau[-1] - tau[0]
    for it in range(1, max_iter + 1):
        a = _design(tau, w, harmonics, drift)
        jw = np.zeros_like(tau)
        for k in range(1, harmonics + 1):
            sk, ck = a[:, 2 * k - 2], a[:, 2 * k - 1]
            jw += k * tau * (coef[2 * k - 2] * ck - coef[2 * k - 1] * sk)
        full = np.column_stack([a, jw])
        sol, _, _ = _lstsq_many(full, y1[None, :], sw)
        dw = float(sol[0, -1])
        # A step beyond a quarter of a DFT bin is not trusted: cap it.
        cap = 0.5 * math.pi / span
        dw = max(-cap, min(cap, dw))
        step = 1.0
        while True:
            new_coef, new_rss = linear(w + step * dw)
            if new_rss <= rss * (1 + 1e-12) or step < 1e-6:
                break
            step *= 0.5
        if new_rss > rss * (1 + 1e-12):
            # No descent possible: at the minimum to rounding.
            converged = True
            break
        w += step * dw
        coef, rss = new_coef, new_rss
        # Stop rule: the step is negligible against the frequency's own
        # standard uncertainty (or against rounding).
        sigma2 = rss / max(tau.size - full.shape[1], 1)
        _, _, ginv = _lstsq_many(full, y1[None, :], sw)
        u_w = math.sqrt(max(sigma2 * ginv[-1, -1], 0.0))
        if abs(step * dw) <= max(1e-4 * u_w, 8e-16 * abs(w)):
            converged = True
            break
    return w, coef, rss, converged, it


# ---------------------------------------------------------------------------
# Transformation to amplitude / phase with covariance
# ---------------------------------------------------------------------------

def _transform(coef, cov_lin, w, harmonics, drift, t_mid, with_freq):
    """Map [s1, c1, ..., sK, cK, offset, (drift), (dw)] to the reported parameters.

    Returns values (q,), covariance (q, q), names.
    """
    p = coef.size
    names = ["amplitude", "phase", "offset"]
    if drift:
        names.append("drift")
    if with_freq:
        names.append("frequency")
    for k in range(2, harmonics + 1):
        names += [f"amplitude_{k}", f"phase_{k}"]
    q = len(names)
    jac = np.zeros((q, p))
    vals = np.zeros(q)
    ioff = 2 * harmonics
    ifr = ioff + 1 + int(drift)
    # Offset: the constant column; with drift it is the value at t_ref = t_mid.
    vals[2] = coef[ioff]
    jac[2, ioff] = 1.0
    row = 3
    if drift:
        vals[row] = coef[ioff + 1]
        jac[row, ioff + 1] = 1.0
        row += 1
    if with_freq:
        vals[row] = w / TWO_PI
        jac[row, ifr] = 1.0 / TWO_PI
        row += 1
    for k in range(1, harmonics + 1):
        s, c = coef[2 * k - 2], coef[2 * k - 1]
        amp = math.hypot(s, c)
        ia, ip = (0, 1) if k == 1 else (row, row + 1)
        vals[ia] = amp
        # Phase at t = 0 from the phase at the centre time (tau = t - t_mid).
        vals[ip] = math.atan2(c, s) - k * w * t_mid
        if amp > 0:
            jac[ia, 2 * k - 2] = s / amp
            jac[ia, 2 * k - 1] = c / amp
            jac[ip, 2 * k - 2] = -c / amp**2
            jac[ip, 2 * k - 1] = s / amp**2
        if with_freq:
            jac[ip, ifr] = -k * t_mid
        if k > 1:
            row += 2
    cov = jac @ cov_lin @ jac.T
    # Phase of the fundamental at the centre time: the same row without the
    # frequency's lever arm.
    jc = jac[1].copy()
    if with_freq:
        jc[ifr] = 0.0
    centre = (math.atan2(coef[1], coef[0]), math.sqrt(max(float(jc @ cov_lin @ jc), 0.0)))
    return vals, cov, tuple(names), centre


# ---------------------------------------------------------------------------
# Public entry point
# ---------------------------------------------------------------------------

def fit_sine(y, t=None, *, fs: float | None = None, freq: float | None = None, harmonics: int = 1,
             weights=None, drift: bool = False, max_iter: int = 100, noise_model: str = "auto") -> SineFit:
    """Least-squares fit of ``y = A sin(2 pi f t + phi) + C`` (+ harmonics, drift).

    Parameters
    ----------
    y : array_like, shape (..., N)
        Samples; leading axes are channels fitted at once on a shared time base.
    t : array_like, shape (N,), optional
        Time stamps in seconds (strictly increasing; not re-zeroed).
    fs : float, optional
        Sample rate in Hz for uniform samples starting at t = 0 (give t or fs).
    freq : float, optional
        Known frequency in Hz: the closed-form three-parameter fit.  When
        omitted the frequency is estimated per channel (interpolated DFT,
        then Gauss-Newton: the four-parameter fit).
    harmonics : int
        Number of harmonics ``K`` (1 = fundamental only); harmonic ``k`` has
        frequency ``k f``.
    weights : array_like, shape (N,) or (..., N), optional
        Relative weights of the samples (e.g. inverse variances); the scale of
        the uncertainties still comes from the weighted residuals.
    drift : bool
        Also fit a linear drift of the offset, ``D (t - t_ref)`` with ``t_ref``
        the record's centre time.
    max_iter : int
        Iteration limit of the frequency estimation.
    noise_model : {"auto", "white", "coloured"}
        How the uncertainties treat the noise.  ``"auto"`` (default): test the
        residual for whiteness (lag-one autocorrelation, 1 % false alarms) and
        switch to the coloured-noise covariance only when the test fails (a
        ``coloured-noise`` warning says so).  ``"white"``: residual variance
        only (a correlated residual is still named in a warning).  ``"coloured"``: always the
        autoregressive noise spectrum.  The coloured model needs a uniform time
        base; on a non-uniform one the white formula is kept and a
        correlated residual is reported as a warning.

    Returns
    -------
    SineFit
        Amplitudes, phases (rad, at t = 0), offset, frequency (Hz) with their
        standard uncertainties and covariance, residual RMS, SNR, THD.

    Raises
    ------
    DataError
        NaN/inf in ``y`` or in ``t``, non-increasing time stamps, or a record
        too short to separate the sine from the offset.
    TooFewSamplesError
        Fewer samples than parameters + 1.
    InputError
        Frequency at or above the Nyquist frequency, bad arguments.
    ConvergenceError
        The frequency iteration found no sinusoid or did not converge.

    Notes
    -----
    Coloured noise: the covariance becomes ``G^-1 (A^T Sigma A) G^-1`` with
    ``Sigma`` the autocovariance of an autoregressive model of the residual
    (order by BIC), see :mod:`senscal.sinefit.noise`; for white noise it is
    ``sigma^2 G^-1``, the Cramer-Rao bound.  The whiteness test of the
    compiled path comes from sums taken in its single pass.

    With a known frequency the fit is linear least squares in the basis
    ``sin(k w tau), cos(k w tau), 1`` on the centred time ``tau = t - t_mid``
    (centring keeps the basis nearly orthogonal, so the normal matrix is well
    conditioned even for ``t0 = 1e5 s``); no explicit inverse is formed for
    the solution.  Uniform, unweighted batches use a compiled one-pass kernel;
    everything else uses an SVD of the (weighted) design matrix.
    """
    # The compiled path checks finiteness inside its single pass over y.
    y = _check_y(y, full=False)
    if noise_model not in ("auto", "white", "coloured"):
        raise InputError(f"noise_model must be 'auto', 'white' or 'coloured', got {noise_model!r}")
    harmonics = int(harmonics)
    if harmonics < 1:
        raise InputError(f"harmonics must be >= 1, got {harmonics}")
    n = y.shape[-1]
    batch = y.shape[:-1]
    tvec, t_mid, dt, first, uniform = _time_base(n, t, fs)
    p = 2 * harmonics + 1 + int(drift) + int(freq is None)
    if n <= p:
        raise TooFewSamplesError(f"{n} samples cannot fit {p} parameters; the fit needs at least {p + 1} samples")
    nyquist = 0.5 / dt
    if freq is not None:
        freq = float(freq)
        if not math.isfinite(freq) or freq <= 0:
            raise InputError(f"frequency must be a positive number of Hz, got {freq!r}")
        if harmonics * freq >= nyquist:
            what = f"harmonic {harmonics} at {harmonics * freq:g} Hz" if harmonics > 1 else f"frequency {freq:g} Hz"
            raise InputError(f"{what} is at or above the Nyquist frequency {nyquist:g} Hz; sample faster or fit fewer harmonics")
        # Below f*T = sqrt(2 eps)/(2 pi) ~ 3.4e-9 the cosine column equals the offset column to float64 rounding
        # (1 - cos x ~ x^2/2 < eps): the model is singular, not merely poorly conditioned.
        if freq * dt * max(n - 1, 1) < math.sqrt(2 * np.finfo(float).eps) / (2 * math.pi):
            raise DataError(f"the record is too short (or the frequency too low) to tell the sine from the offset: "
                            f"{freq:g} Hz spans {freq * dt * max(n - 1, 1):.3g} periods of it; record at least one "
                            "full period or check the unit of --freq")
    sw = None
    per_channel_w = False
    if weights is not None:
        wts = np.asarray(weights, dtype=np.float64)
        if wts.shape == (n,):
            pass
        elif wts.shape == y.shape:
            per_channel_w = True
        else:
            raise InputError(f"weights must have shape ({n},) or {y.shape}, got {wts.shape}")
        if not np.all(np.isfinite(wts)) or np.any(wts < 0) or not np.any(wts > 0):
            raise InputError("weights must be finite, non-negative and not all zero")
        sw = np.sqrt(wts)

    fast = freq is not None and sw is None and uniform
    if not fast:
        _check_y(y, full=True)
    y2 = y.reshape(-1, n)
    nch = y2.shape[0]
    tau0 = float(tvec[0] - t_mid) if tvec is not None else -0.5 * (n - 1) * dt
    # The compiled path generates its own basis; only the others need tau.
    tau = None if fast else ((tvec - t_mid) if tvec is not None else (np.arange(n) - 0.5 * (n - 1)) * dt)
    q_names = None
    vals = []
    covs = []
    rsss = np.empty(nch)
    conv = np.ones(nch, dtype=bool)
    iters = np.zeros(nch, dtype=int)
    freqs = np.empty(nch)

    from senscal.sinefit.noise import coloured_covariance, lag1_significant

    from scipy.stats import chi2 as chi2_dist

    from senscal.sinefit.variance import (LOWFREQ_BINS, VARIANCE_ALPHA, low_frequency_power, phase_variance_batch,
                                          sandwich_covariance)

    lag1s = np.full(nch, np.nan)
    models = np.array(["white"] * nch, dtype=object)
    nus = np.full(nch, float(n - p))
    centres = np.empty((nch, 2))
    test = noise_model == "auto"
    # The variance-against-phase test (jitter) and the low-frequency test (noise below 1/T).
    het_stat = np.full(nch, np.nan)
    het_c = np.full(nch, np.nan)
    het_uc = np.full(nch, np.nan)
    lf_dof = 2 * LOWFREQ_BINS
    het_lim = float(chi2_dist.isf(VARIANCE_ALPHA, 2))
    pre: dict[str, Any] = {}

    lows = np.full(nch, np.nan)

    def residual_tests(rows, resid2, design, coefs):
        """Both tests' sums for channels ``rows`` (residuals ``resid2`` sharing ``design``), vectorised."""
        sn, cs = design[:, 0], design[:, 1]
        if harmonics >= 2:
            # the second harmonic's columns are sin 2 theta and cos 2 theta already
            s2, c2 = design[:, 2], design[:, 3]
        else:
            c2, s2 = cs * cs - sn * sn, 2.0 * sn * cs
        stat, coef, xinv, s2e = phase_variance_batch(resid2, c2, s2)
        amp2 = coefs[:, 0] ** 2 + coefs[:, 1] ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            # Coefficient of cos 2 theta, theta the fitted phase: the (cos, sin)(2 w tau) ones rotated by 2 phi.
            c2p, s2p = (coefs[:, 0] ** 2 - coefs[:, 1] ** 2) / amp2, 2.0 * coefs[:, 0] * coefs[:, 1] / amp2
        het_stat[rows] = np.where(amp2 > 0, stat, np.nan)
        het_c[rows] = coef[:, 1] * c2p - coef[:, 2] * s2p
        vg = c2p**2 * xinv[1, 1] - 2.0 * c2p * s2p * xinv[1, 2] + s2p**2 * xinv[2, 2]
        het_uc[rows] = np.sqrt(np.maximum(vg * s2e, 0.0))
        if n >= 8 * LOWFREQ_BINS:
            lows[rows] = low_frequency_power(resid2)
        pre["mean"] = pre.get("mean", np.full(nch, np.nan))
        pre["pq"] = pre.get("pq", np.full((nch, 2), np.nan))
        pre["mean"][rows], pre["pq"][rows] = coef[:, 0], coef[:, 1:]
        pre["c2"], pre["s2"] = c2, s2

    def bulk_tests(resid_of, design):
        """``residual_tests`` for every channel, 256 channels at a time (bounded memory)."""
        for c0 in range(0, nch, 256):
            c1 = min(c0 + 256, nch)
            resid = resid_of(c0, c1)
            residual_tests(slice(c0, c1), resid, design, coef_all[c0:c1])
            if nch <= 256:
                # one chunk: kept for a channel whose noise model switches (no second pass for its residual)
                pre["resid"] = resid
        pre["bulk"] = True

    def noise_cov(i, resid_w, design_w, ginv, rss_i, omegas, coef_i):
        """White, phase-dependent or coloured covariance of the linear parameters of channel i."""
        if resid_w is not None and rss_i > 0:
            lag1s[i] = float(resid_w[1:] @ resid_w[:-1]) / rss_i
        switch = noise_model == "coloured" or (test and bool(lag1_significant(lag1s[i], n)))
        if switch and uniform and rss_i > 0:
            if design_w is None:
                resid_w, design_w = explicit(i)
            cn = coloured_covariance(resid_w, design_w, ginv, p, omegas)
            models[i] = "coloured"
            nus[i] = cn.dof_effective
            cov_lin = cn.cov_lin
        else:
            cov_lin = ginv * (rss_i / (n - p))
        if sw is not None or not rss_i > 0:
            het_stat[i] = lows[i] = np.nan
            return cov_lin
        if "bulk" not in pre:
            if resid_w is None or design_w is None:
                resid_w, design_w = explicit(i)
            residual_tests(slice(i, i + 1), resid_w[None, :], design_w, np.asarray(coef_i)[None, :])
        # The variance test's null is independent residuals: a correlated one (coloured, or a non-uniform
        # time base that kept the white formula) is named by the whiteness test instead.
        if models[i] != "white" or noise_model == "coloured" or bool(lag1_significant(lag1s[i], n)):
            het_stat[i] = np.nan
        elif test and het_stat[i] > het_lim:
            if design_w is None:
                resid_w, design_w = explicit(i)
            a0 = pre["mean"][i]
            var = np.maximum(a0 + pre["pq"][i, 0] * pre["c2"] + pre["pq"][i, 1] * pre["s2"], 0.01 * max(a0, 0.0))
            models[i] = "phase-dependent"
            cov_lin = sandwich_covariance(design_w, ginv, var, p)
        return cov_lin

    def col_omegas(wv, with_freq):
        om = []
        for k in range(1, harmonics + 1):
            om += [k * wv * dt] * 2
        om.append(0.0)
        if drift:
            om.append(0.0)
        if with_freq:
            om.append(wv * dt)
        return np.array(om)

    if freq is not None:
        w = TWO_PI * freq
        omegas = col_omegas(w, False)
        if fast:
            coef, rss, ginv, lag1_sum, fast_design = _fast_uniform(y2, n, dt, tau0, w, harmonics, drift)
            with np.errstate(divide="ignore", invalid="ignore"):
                lag1s[:] = np.where(rss > 0, lag1_sum / rss, np.nan)
            coef_all = coef
            ginv_all = [ginv] * nch
            resid_all = None

            a_fast = []

            def fast_rows():
                """The design as contiguous rows (p, N), from the pass's own basis: no second set of sines."""
                if not a_fast:
                    # the fundamental's pass generated its basis on the fly: built here once
                    a_fast.append(fast_design if fast_design is not None else
                                  _design_rows(n, dt, tau0, w, harmonics, drift))
                return a_fast[0]

            def explicit(i):
                # the design's transpose is an (N, p) view of the rows (columns contiguous, as FFTs want them)
                rows = fast_rows()
                r = pre["resid"][i] if "resid" in pre else y2[i] - coef_all[i] @ rows
                return r, rows.T
        elif per_channel_w:
            sw2 = sw.reshape(-1, n)
            coef_all = np.empty((nch, p))
            rss = np.empty(nch)
            ginv_all = []
            a = _design(tau, w, harmonics, drift)
            for i in range(nch):
                c, r, g = _lstsq_many(a, y2[i:i + 1], sw2[i])
                coef_all[i], rss[i] = c[0], r[0]
                ginv_all.append(g)
            resid_all = [sw2[i] * (y2[i] - a @ coef_all[i]) for i in range(nch)]

            def explicit(i):
                return resid_all[i], a * sw2[i][:, None]
        else:
            a = _design(tau, w, harmonics, drift)
            coef_all, rss, ginv = _lstsq_many(a, y2, sw)
            ginv_all = [ginv] * nch
            aw = a if sw is None else a * sw[:, None]
            resid_all = (y2 - coef_all @ a.T) if sw is None else (y2 - coef_all @ a.T) * sw[None, :]

            def explicit(i):
                return resid_all[i], aw
        rsss[:] = rss
        freqs[:] = freq
        dof = n - p
        if sw is None and nch > 1:
            # Both residual tests for all channels at once (one pass of matrix products, not one per channel).
            if resid_all is None:
                rows_bulk = fast_rows()
                bulk_tests(lambda c0, c1: y2[c0:c1] - coef_all[c0:c1] @ rows_bulk, rows_bulk.T)
            else:
                bulk_tests(lambda c0, c1: resid_all[c0:c1], explicit(0)[1])
        for i in range(nch):
            if resid_all is None:
                cov_lin = noise_cov(i, None, None, ginv_all[i], rss[i], omegas, coef_all[i])
            else:
                cov_lin = noise_cov(i, *explicit(i), ginv_all[i], rss[i], omegas, coef_all[i])
            v, c, q_names, centres[i] = _transform(coef_all[i], cov_lin, w, harmonics, drift, t_mid, False)
            vals.append(v)
            covs.append(c)
    else:
        dof = n - p
        sw2 = sw.reshape(-1, n) if per_channel_w else None
        for i in range(nch):
            swi = sw2[i] if per_channel_w else sw
            f0 = _initial_frequency(y2[i], tvec, dt, first)
            if harmonics * f0 >= nyquist:
                raise InputError(
                    f"estimated harmonic {harmonics} at {harmonics * f0:g} Hz is above the Nyquist frequency "
                    f"{nyquist:g} Hz; fit fewer harmonics"
                )
            w, coef, rss, ok, it = _fit_unknown(y2[i], tau, swi, f0, harmonics, drift, max_iter)
            if not ok:
                raise ConvergenceError(
                    f"frequency estimate did not converge in {max_iter} iterations"
                    f"{' for channel ' + str(i) if nch > 1 else ''}; give the frequency with freq=/--freq"
                )
            if w <= 0:
                raise ConvergenceError("frequency estimate went to zero or below; the record holds no clear sinusoid; give --freq")
            a = _design(tau, w, harmonics, drift)
            jw = np.zeros_like(tau)
            for k in range(1, harmonics + 1):
                jw += k * tau * (coef[2 * k - 2] * a[:, 2 * k - 1] - coef[2 * k - 1] * a[:, 2 * k - 2])
            full = np.column_stack([a, jw])
            _, _, ginv = _lstsq_many(full, y2[i:i + 1], swi)
            resid = y2[i] - a @ coef
            fw = full
            if swi is not None:
                resid = resid * swi
                fw = full * swi[:, None]
            cov_lin = noise_cov(i, resid, fw, ginv, rss, col_omegas(w, True), coef)
            coef_ext = np.append(coef, 0.0)
            v, c, q_names, centres[i] = _transform(coef_ext, cov_lin, w, harmonics, drift, t_mid, True)
            vals.append(v)
            covs.append(c)
            rsss[i] = rss
            conv[i] = ok
            iters[i] = it
            freqs[i] = w / TWO_PI

    vals_a = np.array(vals)
    cov_a = np.array(covs)
    names = q_names
    idx = {nm: j for j, nm in enumerate(names)}
    # The low-frequency test: the lowest bins' power against the level u(offset) implies (N u^2).
    with np.errstate(divide="ignore", invalid="ignore"):
        u_off2 = cov_a[:, idx["offset"], idx["offset"]]
        lf_stat = np.where(u_off2 > 0, 2.0 * lows / (n * u_off2), np.nan)
    if not np.any(np.isfinite(lf_stat)):
        lf_dof = 0
    amp_idx = [idx["amplitude"]] + [idx[f"amplitude_{k}"] for k in range(2, harmonics + 1)]
    # Jitter shrinks harmonic k by exp(-k^2 w^2 delta^2 / 2); the cos(2 theta) coefficient of the
    # residual variance, c = A^2 w^2 delta^2 / 2, measures it (with its u) where the test found it.
    jitter = np.full(nch, np.nan)
    for i in np.flatnonzero((models == "phase-dependent") & (het_c > 0)):
        a1 = vals_a[i, idx["amplitude"]]
        if not a1 > 0:
            continue
        jitter[i] = math.sqrt(2.0 * het_c[i]) / a1 / (TWO_PI * freqs[i])
        for k, j in enumerate(amp_idx, start=1):
            g = math.exp(k * k * het_c[i] / a1**2)
            vals_a[i, j] *= g
            cov_a[i, j, :] *= g
            cov_a[i, :, j] *= g
            cov_a[i, j, j] += (vals_a[i, j] * k * k * het_uc[i] / a1**2) ** 2
    u = np.sqrt(np.maximum(np.diagonal(cov_a, axis1=1, axis2=2), 0.0))
    ph_idx = [idx["phase"]] + [idx[f"phase_{k}"] for k in range(2, harmonics + 1)]
    h_amp = vals_a[:, amp_idx]
    h_ph = wrap_phase(vals_a[:, ph_idx])
    u_h_amp = u[:, amp_idx]
    u_h_ph = u[:, ph_idx]
    # Weighted RMS so that uniform weights give the plain RMS.
    if sw is None:
        res_ms = rsss / n
    else:
        wsum = (sw.reshape(-1, n) ** 2).sum(axis=1) if per_channel_w else np.full(nch, float((sw**2).sum()))
        res_ms = rsss / wsum
    res_rms = np.sqrt(res_ms)
    with np.errstate(divide="ignore", invalid="ignore"):
        snr = 10.0 * np.log10((h_amp[:, 0] ** 2 / 2.0) / res_ms)
    thd = None
    if harmonics > 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            thd = np.sqrt((h_amp[:, 1:] ** 2).sum(axis=1)) / h_amp[:, 0]
    u_freq = u[:, idx["frequency"]] if "frequency" in idx else np.zeros(nch)

    def shaped(a):
        a = np.asarray(a)
        out = a.reshape(batch + a.shape[1:])
        return out.item() if out.ndim == 0 else out

    return SineFit(
        frequency=shaped(freqs),
        amplitude=shaped(h_amp[:, 0]),
        phase=shaped(h_ph[:, 0]),
        offset=shaped(vals_a[:, idx["offset"]]),
        u_frequency=shaped(u_freq),
        u_amplitude=shaped(u[:, idx["amplitude"]]),
        u_phase=shaped(u[:, idx["phase"]]),
        u_offset=shaped(u[:, idx["offset"]]),
        covariance=cov_a.reshape(batch + cov_a.shape[1:]),
        parameter_names=names,
        harmonic_amplitudes=h_amp.reshape(batch + (harmonics,)),
        harmonic_phases=np.asarray(h_ph).reshape(batch + (harmonics,)),
        u_harmonic_amplitudes=u_h_amp.reshape(batch + (harmonics,)),
        u_harmonic_phases=u_h_ph.reshape(batch + (harmonics,)),
        thd=None if thd is None else shaped(thd),
        drift=shaped(vals_a[:, idx["drift"]]) if drift else None,
        u_drift=shaped(u[:, idx["drift"]]) if drift else None,
        t_ref=float(t_mid),
        residual_rms=shaped(res_rms),
        snr_db=shaped(snr),
        n_samples=int(n),
        dof=int(dof),
        converged=shaped(conv),
        iterations=shaped(iters),
        frequency_estimated=freq is None,
        phase_centre=shaped(wrap_phase(centres[:, 0])),
        u_phase_centre=shaped(centres[:, 1]),
        noise_model=shaped(models) if batch else str(models[0]),
        dof_effective=shaped(nus),
        residual_lag1=shaped(lag1s),
        variance_phase_stat=shaped(het_stat),
        jitter_rms=shaped(jitter),
        lowfreq_chi2=shaped(lf_stat),
        lowfreq_dof=int(lf_dof),
        warnings=fit_warnings(shaped(models) if batch else str(models[0]), shaped(lag1s), shaped(nus),
                              shaped(u[:, idx["phase"]]), float(t_mid), int(n), freq is None,
                              variance_phase_stat=shaped(het_stat), jitter_rms=shaped(jitter),
                              lowfreq_chi2=shaped(lf_stat), lowfreq_dof=int(lf_dof), drift=drift),
    )
