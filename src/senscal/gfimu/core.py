"""Angular velocity from an accelerometer array: the whole pipeline.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5) (seed 001); METHODS.md 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np
from scipy.stats import binom, chi2

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import InputError, TooFewSamplesError
from senscal.gfimu.filter import OBSERVATIONS, RateFilterResult, channel_covariance, kalman_rate
from senscal.gfimu.layout import KinematicSolution, Layout, solve_kinematics, square_map
from senscal.gfimu.methods import differential_rate, estimate_noise_std, integration_rate, sqrt_rate

__all__ = ["METHODS", "DEFAULT_BIAS_STD", "RestOffsets", "RateEstimate", "ErrorStatistics", "ScaleFactorTest",
           "angular_velocity", "error_statistics", "rest_offsets", "scale_factor_test", "convergence_index",
           "CONVERGENCE_FACTOR"]

#: The filter has converged once its stated u(w) stays within this factor of its median over the record.
CONVERGENCE_FACTOR = 2.0

#: Methods in the order the paper presents them.
METHODS = ("integration", "sqrt", "differential", "kalman")

#: Default standard uncertainty of each channel's constant error, m/s^2 (about 10 mg, the zero-g offset of a
#: MEMS accelerometer after a factory trim).  The filter learns the constant errors from the motion, so the
#: rate band is insensitive to this prior (coverage is unchanged from 1e-4 g to 5e-2 g on the paper's
#: simulation); it only has to be wide enough to hold the true errors.
DEFAULT_BIAS_STD = 0.1

#: False-alarm probability of the model checks (gating count, innovation consistency, rest segment).
CHECK_PROBABILITY = 1e-6


@dataclass(frozen=True)
class RestOffsets(ResultMixin):
    """Constant errors of the kinematics measured on a segment where the body is at rest.

    At rest ``alpha = 0`` and ``W = 0``, so the mean of the solved
    ``alpha`` and ``W`` over the segment is the image of the channel biases
    (and of any static mounting error) in them; the specific force takes the
    rest (gravity), which is why the 12 channel biases themselves are not
    all identifiable, only these nine combinations, which are all the rate
    estimate needs.

    Attributes
    ----------
    span : tuple of float
        Start and end of the segment, s.
    n : int
        Samples in the segment.
    offsets : ndarray, shape (9,)
        ``alpha`` (rad/s^2) and ``W`` ((rad/s)^2) offsets, UNKNOWNS[3:] order.
    u_offsets : ndarray, shape (9,)
        Standard uncertainties (white channel noise averaged over the segment).
    covariance : ndarray, shape (9, 9)
    spread_ratio : float
        Observed over expected variance of the kinematics inside the segment
        (1 when the body really is at rest).
    mask : ndarray of bool, shape (T,)
        The segment's samples.
    """

    span: tuple
    n: int
    offsets: np.ndarray
    u_offsets: np.ndarray
    covariance: np.ndarray = field(repr=False)
    spread_ratio: float
    mask: np.ndarray = field(default=None, repr=False)


def rest_offsets(kin: KinematicSolution, t: np.ndarray, noise_std, span) -> RestOffsets:
    """Measure the nine constant errors of ``alpha`` and ``W`` on a rest segment.

    Parameters
    ----------
    kin : KinematicSolution
    t : ndarray, shape (T,)
        Time, s.
    noise_std : float or ndarray, shape (M,)
        White-noise standard deviation of each channel, m/s^2.
    span : tuple (start, end)
        The segment, s: ``start <= t < end``.

    Returns
    -------
    RestOffsets
    """
    a, b = (float(v) for v in span)
    if not (np.isfinite(a) and np.isfinite(b) and b > a):
        raise InputError(f"the rest segment must be START:END in s with END > START, got {a:g}:{b:g}")
    # Half-open, like a slice: "--rest 0:2" on a record whose motion starts at t = 2 s is all rest.
    sel = (t >= a) & (t < b)
    n = int(sel.sum())
    if n < 10:
        raise InputError(f"the rest segment {a:g}:{b:g} s holds {n} samples of the recording "
                         f"(t = {t[0]:g}..{t[-1]:g} s); give a segment of at least 10 samples inside it")
    C = channel_covariance(kin, noise_std)[3:12, 3:12]
    x = kin.x[3:12, sel]
    c = x.mean(axis=1)
    # Whitened spread of the segment: chi-square with 9 (n - 1) degrees of freedom when the body is at rest.
    L = np.linalg.cholesky(C)
    r = np.linalg.solve(L, x - c[:, None])
    ratio = float(np.sum(r * r) / (9 * (n - 1)))
    return RestOffsets(span=(a, b), n=n, offsets=c, u_offsets=np.sqrt(np.diag(C) / n), covariance=C / n,
                       spread_ratio=ratio, mask=sel)


@dataclass(frozen=True)
class RateEstimate(ResultMixin):
    """Angular velocity of a rigid body from its accelerometer array.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Time, s.
    omega : dict of str to ndarray (3, T)
        Angular velocity per method, rad/s (NaN where the differential
        method rejected a sample).
    u_omega : ndarray, shape (3, T) or None
        Standard uncertainty of the Kalman estimate (white noise only), rad/s.
    kinematics : KinematicSolution
        Specific force, angular acceleration and quadratic terms per sample.
    noise_std : ndarray, shape (M,)
        White-noise standard deviation of each channel used (m/s^2).
    condition_number : float
        Scale-free condition number of the layout.
    filter : RateFilterResult or None
        Diagnostics of the Kalman filter.
    differential_rejected : int
        Samples x axes the differential method rejected as ill-conditioned.
    rest : RestOffsets or None
        Constant errors measured on the user's rest segment.
    noise_scale : float
        Factor on the channel noise of the final Kalman run: 1, or (when the
        innovations showed a departure from the model and the noise was
        estimated, not given) the factor that made the innovations
        consistent again (see the ``filter-gated`` and
        ``innovations-inconsistent`` warnings).
    warnings : tuple of str
        Named warnings (:mod:`senscal.diagnostics`): ``constant-errors-ignored``,
        ``filter-gated``, ``innovations-inconsistent``, ``rest-not-at-rest``.
    """

    t: np.ndarray = field(repr=False)
    omega: dict = field(repr=False)
    u_omega: np.ndarray | None = field(repr=False)
    kinematics: KinematicSolution = field(repr=False)
    noise_std: np.ndarray
    condition_number: float
    filter: RateFilterResult | None
    differential_rejected: int
    rest: RestOffsets | None = None
    noise_scale: float = 1.0
    warnings: tuple = ()


def angular_velocity(readings: np.ndarray, t: np.ndarray, layout: Layout, *,
                     methods: Sequence[str] = ("kalman",), observation: str = "quadratic",
                     initial=(0.0, 0.0, 0.0), noise_std=None, lag: int = 1,
                     gate_probability: float = 1e-4, bias_std=None, smooth: bool = False, plain: bool = False,
                     rest=None, differential_max_u: float | None = None, reset_after: int = 5) -> RateEstimate:
    """Solve the array's kinematics and estimate ``w`` by the chosen methods.

    Parameters
    ----------
    readings : ndarray, shape (M, T)
        Accelerometer readings in m/s^2, rows in ``layout.names`` order.
    t : ndarray, shape (T,)
        Time, s (strictly increasing).
    layout : Layout
        Positions (m) and directions of the channels.
    methods : sequence of str
        Any of ``"integration"``, ``"sqrt"``, ``"differential"``, ``"kalman"``.
    observation : {"quadratic", "sqrt", "differential"}
        Observation of the Kalman filter (see :func:`kalman_rate`).
    initial : sequence of 3 floats or None
        Angular velocity at ``t[0]``, rad/s (default: at rest).  ``None``
        lets the linear Kalman filters start from their first observations.
    noise_std : float or ndarray (M,), optional
        White-noise standard deviation of the channels, m/s^2; estimated
        from the second differences of the readings when omitted.
    lag : int
        Span of the differential method in samples (1: the paper's).
    gate_probability : float
        False-rejection probability of the filter's innovation gate.
    bias_std : float or ndarray (M,), optional
        Standard uncertainty of the channels' constant errors, m/s^2
        (default :data:`DEFAULT_BIAS_STD`); the quadratic Kalman filter
        estimates the constant errors they put into the kinematics (see
        :func:`kalman_rate`) and ``u_omega`` includes what remains of them.
    smooth : bool
        Offline: the Kalman estimate is the fixed-interval (RTS) smoother's
        (uses the whole record; the default filter is causal).
    plain : bool
        The paper's plain filter: no constant-error states, so ``u_omega``
        holds white noise only and does not cover the truth when the
        channels have biases (warning ``constant-errors-ignored``).  The
        ``sqrt`` and ``differential`` observations are always plain.
    rest : tuple (start, end), optional
        A segment (s) where the body is at rest: the constant errors of the
        kinematics are measured there (:func:`rest_offsets`) and start the
        filter's constant-error states instead of the ``bias_std`` prior.
    differential_max_u : float, optional
        Absolute rejection threshold of the differential method (and
        observation), rad/s: samples whose standard uncertainty exceeds it
        are rejected (the relative 3x-median rule alone passes gross errors
        on an axis that hardly turns).
    reset_after : int
        Consecutive gated samples after which the quadratic filter widens
        its rate covariance to re-acquire the measurements (0: never).

    Returns
    -------
    RateEstimate

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), sections 1.3-3.
    """
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise InputError(f"unknown method {', '.join(bad) or '(none)'}; choose from {', '.join(METHODS)}")
    if observation not in OBSERVATIONS:
        raise InputError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {observation!r}")
    t = np.asarray(t, float)
    y = np.asarray(readings, float)
    if y.ndim != 2 or y.shape[1] != t.size:
        raise InputError(f"readings must have shape (M, T) matching t of {t.size} samples, got {y.shape}")
    if t.size < 8:
        raise TooFewSamplesError(f"angular velocity from the array needs at least 8 samples, got {t.size}")
    kin = solve_kinematics(y, layout)
    sig = estimate_noise_std(y) if noise_std is None else np.broadcast_to(np.asarray(noise_std, float), (y.shape[0],))
    if not np.all(np.isfinite(sig)) or np.any(sig < 0):
        raise InputError("noise_std must be non-negative numbers (m/s^2)")
    if differential_max_u is not None and not differential_max_u > 0:
        raise InputError(f"differential_max_u must be a positive rate in rad/s, got {differential_max_u}")
    # A noise-free record still needs a non-singular observation covariance.
    sig = np.maximum(sig, 1e-12)
    w0 = None if initial is None else np.asarray(initial, float).reshape(3)
    out: dict[str, np.ndarray] = {}
    alpha, squares = kin.angular_acceleration, kin.squares
    w_int = integration_rate(alpha, t, np.zeros(3) if w0 is None else w0)
    if "integration" in methods:
        out["integration"] = w_int
    if "sqrt" in methods:
        out["sqrt"] = sqrt_rate(squares, w_int)
    n_rej = 0
    if "differential" in methods:
        C = channel_covariance(kin, sig)
        S = square_map()
        s_sq = np.sqrt(np.diag(S @ C[6:9, 6:9] @ S.T))
        w_d, _, rej = differential_rate(squares, alpha, t, lag=lag, squares_std=s_sq,
                                        max_uncertainty=differential_max_u)
        out["differential"] = w_d
        n_rej = int(rej.sum())
    filt = None
    u_om = None
    warns: list[str] = []
    noise_scale = 1.0
    rest_res = rest_offsets(kin, t, sig, rest) if rest is not None else None
    if rest_res is not None:
        dof = 9 * (rest_res.n - 1)
        if rest_res.spread_ratio > chi2.isf(CHECK_PROBABILITY, dof) / dof:
            warns.append(named("rest-not-at-rest", (
                f"the kinematics vary {rest_res.spread_ratio:.3g}x more than white noise inside the rest segment "
                f"{rest_res.span[0]:g}:{rest_res.span[1]:g} s, so the body moved there and the constant errors "
                "measured on it are wrong; mark a segment where the body is still")))
    if "kalman" in methods:
        states = observation == "quadratic" and not plain
        if plain and (bias_std is not None or rest is not None):
            raise InputError("plain (the paper's filter) has no constant-error states: drop bias_std and rest")
        if bias_std is not None and rest is not None:
            raise InputError("rest replaces the bias_std prior of the constant-error states: give one of them")
        if not states and (bias_std is not None or rest is not None):
            raise InputError("bias_std and rest (constant-error states) need the quadratic observation")
        b = (DEFAULT_BIAS_STD if bias_std is None else bias_std) if states else None
        prior = (rest_res.offsets, rest_res.covariance) if (states and rest_res is not None) else None
        def run(s):
            return kalman_rate(kin, t, s, observation=observation, initial=w0, lag=lag,
                               gate_probability=gate_probability, bias_std=b, smooth=smooth,
                               reset_after=reset_after, offsets_prior=prior,
                               prior_samples=None if prior is None else rest_res.mask)

        filt = run(sig)
        fw = _filter_warnings(filt, states, gate_probability)
        if states:
            fw += _scale_factor_warning(scale_factor_test(kin, y, filt), layout)
            # The inverse covariances served the test; a result does not keep 36 numbers a sample.
            filt = replace(filt, innovation_inv_cov=None)
        mismatch = any(w.startswith(("filter-gated", "innovations-")) for w in fw)
        if noise_std is None and filt.nis is not None and mismatch:
            # The measurements disagree with the model by more than white noise: re-run with the channel
            # noise scaled to the innovations (median NIS over its chi-square median), so that the filter
            # tracks them instead of gating most of them.  The warnings of the first run stand: the
            # departure is correlated in time, so the rescaled u still understates the error.
            for _ in range(3):
                r = float(np.nanmedian(filt.nis) / chi2.median(6))
                if not (np.isfinite(r) and r > 1.5):
                    break
                noise_scale *= math.sqrt(r)
                filt = run(sig * noise_scale)
            fw = [w + f" (re-estimated with the channel noise scaled {noise_scale:.3g}x to the innovations)"
                  if w.startswith(("filter-gated", "innovations-")) else w for w in fw]
        out["kalman"] = filt.omega
        u_om = filt.u_omega
        if states and filt.innovation_inv_cov is not None:
            filt = replace(filt, innovation_inv_cov=None)
        warns.extend(fw)
    ordered = {m: out[m] for m in METHODS if m in out}
    return RateEstimate(t=t, omega=ordered, u_omega=u_om, kinematics=kin, noise_std=np.asarray(sig),
                        condition_number=kin.condition_number, filter=filt, differential_rejected=n_rej,
                        rest=rest_res, noise_scale=noise_scale, warnings=tuple(warns))


@dataclass(frozen=True)
class ScaleFactorTest(ResultMixin):
    """Score test of per-channel scale-factor errors on the filter's innovations.

    A channel reading ``(1 + e_i) a_i`` instead of ``a_i`` puts
    ``K_W diag(a) e`` into the six quadratic terms the filter observes
    (``K_W``: the rows of the solve's sensitivity for them); the
    constant-error states absorb only its constant part. Under the array
    model the innovations ``nu_k`` are independent ``N(0, S_k)``, so the
    score ``g = sum_k G_k' S_k^-1 nu_k`` with ``G_k = K_W diag(a_k)`` has
    mean zero and covariance ``F = sum_k G_k' S_k^-1 G_k``, and
    ``g' F^+ g`` is chi-square with ``rank(F)`` degrees of freedom (the
    Lagrange-multiplier test of ``e = 0``). The regressor takes ``a_k`` from
    the next reading ``y_{k+1}``: the causal filter's ``nu_k`` holds the
    white noise of samples up to ``k`` only, while the noise of ``y_k``
    itself is in ``nu_k`` through near-singular directions of the solve and
    would dominate the score.

    Attributes
    ----------
    statistic : float
        ``g' F^+ g``.
    dof : int
        Rank of ``F`` (at most the number of channels).
    p_value : float
        Chi-square tail probability of ``statistic``.
    scale : ndarray, shape (M,)
        One-step estimate ``F^+ g`` of the scale-factor errors (fractions); the
        filter's states absorb part of a real error, so it underestimates.
    n : int
        Innovations used (accepted by the gate).
    """

    statistic: float
    dof: int
    p_value: float
    scale: np.ndarray
    n: int


def scale_factor_test(kin: KinematicSolution, readings: np.ndarray, filt: RateFilterResult, *,
                      chunk: int = 4096) -> ScaleFactorTest | None:
    """The score test of :class:`ScaleFactorTest` on a quadratic filter with constant-error states.

    Parameters
    ----------
    kin : KinematicSolution
    readings : ndarray, shape (M, T)
        The readings the kinematics were solved from, m/s^2.
    filt : RateFilterResult
        With ``innovations`` and ``innovation_inv_cov`` (the constant-error filter).

    Returns
    -------
    ScaleFactorTest or None
        None when the filter kept fewer than two innovations.
    """
    if filt.innovations is None or filt.innovation_inv_cov is None:
        return None
    nu, si = filt.innovations, filt.innovation_inv_cov
    ok = np.isfinite(nu).all(axis=0)
    if filt.gated is not None:
        ok &= ~filt.gated
    ok[-1] = False  # no next reading
    idx = np.flatnonzero(ok)
    if idx.size < 2:
        return None
    y = np.asarray(readings, float)
    Kw = kin.sensitivity[6:12]
    m = Kw.shape[1]
    g = np.zeros(m)
    F = np.zeros((m, m))
    for a in range(0, idx.size, chunk):
        k = idx[a:a + chunk]
        Sk = np.moveaxis(si[:, :, k], -1, 0)                       # (n, 6, 6)
        v = np.einsum("nij,jn->ni", Sk, nu[:, k])                   # S^-1 nu
        yk = y[:, k + 1].T                                          # (n, M): the next reading
        g += np.einsum("nm,im,ni->m", yk, Kw, v)
        A = np.einsum("im,nij,jl->nml", Kw, Sk, Kw)                 # K_W' S^-1 K_W
        F += np.einsum("nm,nml,nl->ml", yk, A, yk)
    w, V = np.linalg.eigh(0.5 * (F + F.T))
    keep = w > 1e-10 * max(float(w.max()), 1e-300)
    proj = V[:, keep].T @ g
    stat = float(np.sum(proj ** 2 / w[keep]))
    dof = int(keep.sum())
    est = V[:, keep] @ (proj / w[keep])
    return ScaleFactorTest(statistic=stat, dof=dof, p_value=float(chi2.sf(stat, dof)), scale=est, n=int(idx.size))


def _scale_factor_warning(test: ScaleFactorTest | None, layout: Layout) -> list[str]:
    """``scale-factor-mismatch`` when the score test rejects unit gains at :data:`CHECK_PROBABILITY`."""
    if test is None or test.dof == 0 or test.statistic <= chi2.isf(CHECK_PROBABILITY, test.dof):
        return []
    i = int(np.argmax(np.abs(test.scale)))
    return [named("scale-factor-mismatch", (
        f"the filter's innovations follow the channels' readings (score test of per-channel scale factors: "
        f"chi-square {test.statistic:.4g} on {test.dof} degrees of freedom, p = {test.p_value:.2g}): the channels' "
        f"gains differ from the layout's unit gains (largest one-step estimate {100 * test.scale[i]:+.2g} % on "
        f"'{layout.names[i]}'), which u(w) does not include; calibrate the channels' sensitivities"))]


def _filter_warnings(filt: RateFilterResult, states: bool, gate_probability: float) -> list[str]:
    """Named warnings on a Kalman rate estimate: what its u leaves out, and tests of its model."""
    out = []
    if not states:
        out.append(named("constant-errors-ignored", (
            f"the {filt.observation} filter without constant-error states leaves the channels' biases out of "
            "u(w), which then covers the truth far less than 95 %; use the quadratic observation with "
            "constant-error states (the default, or --bias-std / --rest)")))
    n = filt.omega.shape[1]
    if gate_probability > 0:
        # Under the model the gated count is binomial(n, gate_probability).
        limit = int(binom.isf(CHECK_PROBABILITY, n, gate_probability))
        if filt.n_gated > limit:
            out.append(named("filter-gated", (
                f"the innovation gate rejected {filt.n_gated} of {n} samples ({100 * filt.n_gated / n:.3g} %, "
                f"at most {limit} expected when the array model holds): the measurements disagree with the "
                "layout (mounting position/direction or scale-factor errors, a wrong layout or noise level), "
                "u(w) does not describe the error; calibrate the layout, or mark a rest segment (--rest)")))
    if filt.nis is not None and filt.gated is not None:
        ok = ~filt.gated & np.isfinite(filt.nis)
        m = ok.sum()
        if m > 0:
            dof = 6 * int(m)
            mean = float(filt.nis[ok].sum() / m)
            limit = float(chi2.isf(CHECK_PROBABILITY, dof) / m)
            if mean > limit:
                out.append(named("innovations-inconsistent", (
                    f"the filter's accepted innovations are {mean / 6:.3g}x larger than the array model "
                    f"predicts (mean NIS {mean:.3g}, at most {limit:.3g} expected for 6 terms): a departure "
                    "from the model (mounting errors, scale factors, wrong noise level) that u(w) does not "
                    "include; calibrate the layout or give --noise-std")))
    return out


@dataclass(frozen=True)
class ErrorStatistics(ResultMixin):
    """Error of one method against the truth, per axis (the paper's Table 2).

    Attributes
    ----------
    method : str
    max_abs_error : ndarray, shape (3,)
        Largest absolute error per axis over the valid samples, rad/s.
    std_error : ndarray, shape (3,)
        Standard deviation of the error per axis, rad/s.
    mean_error : ndarray, shape (3,)
        Mean error per axis, rad/s.
    n_valid : ndarray, shape (3,)
        Samples compared per axis (rejected samples excluded).
    """

    method: str
    max_abs_error: np.ndarray
    std_error: np.ndarray
    mean_error: np.ndarray
    n_valid: np.ndarray

    def axis(self, i: int) -> dict:
        return {"max_abs_error": float(self.max_abs_error[i]), "std_error": float(self.std_error[i]),
                "mean_error": float(self.mean_error[i]), "n_valid": int(self.n_valid[i])}


def convergence_index(u_omega: np.ndarray, factor: float = CONVERGENCE_FACTOR) -> int:
    """First sample of a Kalman estimate's converged part (0 when there is no start-up transient).

    The filter starts at rest with its constant errors unknown: its stated
    ``u(w)`` first grows (the unknown offsets integrate) and then settles as
    it learns them, and its error does the same. The converged part starts
    after the last sample in the record's first half at which any axis's
    ``u(w)`` exceeds ``factor`` times that axis's median over the record
    (later excursions belong to the motion, not the start-up).

    Parameters
    ----------
    u_omega : ndarray, shape (3, T)
        The filter's standard uncertainty of ``w``, rad/s.
    factor : float
        How far above its median ``u(w)`` may still be once converged.

    Returns
    -------
    int
        Index of the first converged sample.
    """
    u = np.asarray(u_omega, float)
    if u.ndim != 2 or u.shape[1] < 2:
        return 0
    med = np.nanmedian(u, axis=1)
    above = np.any(u > factor * med[:, None], axis=0)
    above[u.shape[1] // 2:] = False
    idx = np.flatnonzero(above)
    return int(idx[-1] + 1) if idx.size else 0


def error_statistics(omega: dict, truth: np.ndarray, *, skip: int = 0) -> dict[str, ErrorStatistics]:
    """Max absolute error and standard deviation of each method against the truth.

    Parameters
    ----------
    omega : dict of str to ndarray (3, T)
        Estimates per method, rad/s (NaN samples are left out).
    truth : ndarray, shape (3, T)
        True angular velocity, rad/s.
    skip : int
        Leading samples left out (filter start-up), default none.

    Returns
    -------
    dict of str to ErrorStatistics

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), Table 2.
    """
    truth = np.asarray(truth, float)
    res = {}
    for name, est in omega.items():
        est = np.asarray(est, float)
        if est.shape != truth.shape:
            raise InputError(f"truth has shape {truth.shape} but the {name} estimate {est.shape}; "
                             "the truth must share the recording's time base")
        e = (est - truth)[:, skip:]
        ok = np.isfinite(e)
        n = ok.sum(axis=1)
        with np.errstate(invalid="ignore"):
            ez = np.where(ok, e, 0.0)
            mean = np.where(n > 0, ez.sum(axis=1) / np.maximum(n, 1), np.nan)
            var = np.where(n > 1, (np.where(ok, e - mean[:, None], 0.0) ** 2).sum(axis=1) / np.maximum(n - 1, 1), np.nan)
            mx = np.where(n > 0, np.abs(ez).max(axis=1), np.nan)
        res[name] = ErrorStatistics(method=name, max_abs_error=mx, std_error=np.sqrt(var), mean_error=mean, n_valid=n)
    return res
