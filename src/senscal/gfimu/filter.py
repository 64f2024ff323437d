"""The independent Kalman filter for the array's angular velocity.

State: ``w = (wx, wy, wz)``.  Process (the integration method):
``w_k = w_{k-1} + D_k + noise``, with ``D_k`` the trapezoid increment of the
array's angular acceleration as the control input and the process noise the
white-noise variance of that increment.  Observation: ``w`` from the
square-root method or from the differential method, each with a noise
covariance that follows its own conditioning (the square root's error
grows as ``1 / |w|``, the differential's as ``1 / |D|``), or (beyond the
paper) the six quadratic terms ``w w^T - |w|^2 I`` themselves through an
extended Kalman filter.  Ill-conditioned observations are dropped and
innovation gating rejects gross outliers.  The linear filters run on the
shared :mod:`senscal.kalman` engine.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5), section 3 (seed 001);
   METHODS.md 2d.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2

from senscal._result import ResultMixin
from senscal.errors import InputError
from senscal.kalman import KalmanResult, StateSpaceModel, kalman_filter, rts_smoother
from senscal.gfimu._kernels import quadratic_ekf, quadratic_ekf_offsets
from senscal.gfimu.layout import KinematicSolution, square_map
from senscal.gfimu.methods import differential_rate, integration_rate, rate_increments, sqrt_rate

OBSERVATIONS = ("quadratic", "sqrt", "differential")

__all__ = ["RateFilterResult", "channel_covariance", "OBSERVATIONS", "kalman_rate", "sqrt_observation",
           "differential_observation"]


@dataclass(frozen=True)
class RateFilterResult(ResultMixin):
    """Output of :func:`kalman_rate`.

    Attributes
    ----------
    omega : ndarray, shape (3, T)
        Filtered angular velocity, rad/s.
    u_omega : ndarray, shape (3, T)
        Its standard uncertainty from the filter covariance (white noise
        only; constant sensor errors are not in it), rad/s.
    observation : str
        ``"quadratic"``, ``"sqrt"`` or ``"differential"``.
    n_observed : int
        Samples with at least one observation component used.
    n_dropped : int
        Observation components dropped as ill-conditioned.
    n_gated : int
        Samples whose observation the innovation gate rejected.
    passes : int
        Filter passes run (the square-root observation takes its sign from
        the previous pass).
    offsets : ndarray, shape (9,) or None
        With ``bias_std``: the estimated constant errors of the angular
        acceleration (rad/s^2) and of the six quadratic terms ((rad/s)^2),
        in :data:`~senscal.gfimu.layout.UNKNOWNS` order (``alpha_x`` ...
        ``W_yz``), at the end of the record.
    u_offsets : ndarray, shape (9,) or None
        Their standard uncertainties.
    smoothed : bool
        ``omega`` is the offline fixed-interval (RTS) smoother's, not the
        causal filter's.
    nis : ndarray, shape (T,) or None
        Normalised innovation squared of every sample (quadratic
        observation: chi-square with 6 degrees of freedom when the model
        holds), before gating.
    gated : ndarray of bool, shape (T,) or None
        Samples the innovation gate rejected.
    innovations : ndarray, shape (6, T) or None
        Quadratic observation with constant-error states: the causal
        filter's innovations (NaN where a sample was only predicted).
    innovation_inv_cov : ndarray, shape (6, 6, T) or None
        Their inverse covariances (for score tests of unmodelled errors).
    """

    omega: np.ndarray = field(repr=False)
    u_omega: np.ndarray = field(repr=False)
    observation: str
    n_observed: int
    n_dropped: int
    n_gated: int
    passes: int
    offsets: np.ndarray | None = None
    u_offsets: np.ndarray | None = None
    smoothed: bool = False
    nis: np.ndarray | None = field(default=None, repr=False)
    gated: np.ndarray | None = field(default=None, repr=False)
    innovations: np.ndarray | None = field(default=None, repr=False)
    innovation_inv_cov: np.ndarray | None = field(default=None, repr=False)


def sqrt_observation(squares: np.ndarray, cov_squares: np.ndarray, sign_reference: np.ndarray,
                     magnitude_reference: np.ndarray | None = None, *, min_snr: float = 5.0):
    """Square-root observation of ``w`` and its conditioning-aware covariance.

    Parameters
    ----------
    squares : ndarray, shape (3, T)
        ``wx^2, wy^2, wz^2``, (rad/s)^2.
    cov_squares : ndarray, shape (3, 3)
        Covariance of one sample of the squares from white channel noise, (rad/s)^4.
    sign_reference : ndarray, shape (3, T)
        Angular velocity that gives the sign, rad/s.
    magnitude_reference : ndarray, shape (3, T), optional
        ``|w|`` used to linearise the root (default: the observation itself), rad/s.
    min_snr : float
        Components whose square is below ``min_snr`` standard deviations are
        dropped: there the root is biased and its sign unknowable.

    Returns
    -------
    z : ndarray, shape (3, T)
        Observation (NaN where dropped), rad/s.
    R : ndarray, shape (3, 3, T)
        ``cov(sqrt) = J C J`` with ``J = diag(1 / (2 |w|))``, (rad/s)^2.
    """
    s = np.sqrt(np.diag(cov_squares))
    z = sqrt_rate(squares, sign_reference)
    z[squares < min_snr * s[:, None]] = np.nan
    mag = np.abs(z) if magnitude_reference is None else np.abs(magnitude_reference)
    # Below sqrt(s) the linearisation of the root fails: floor the magnitude there.
    mag = np.maximum(np.nan_to_num(mag, nan=0.0), np.sqrt(s)[:, None])
    j = 0.5 / mag
    R = cov_squares[:, :, None] * j[:, None, :] * j[None, :, :]
    return z, R


def differential_observation(squares: np.ndarray, alpha: np.ndarray, t: np.ndarray, cov_squares: np.ndarray,
                             *, lag: int = 1, reject_factor: float = 3.0):
    """Differential observation of ``w`` and its covariance (diagonal).

    Returns ``z`` (3, T) with NaN where rejected and ``R`` (3, 3, T).
    """
    s = np.sqrt(np.diag(cov_squares))
    z, u, _ = differential_rate(squares, alpha, t, lag=lag, squares_std=s, reject_factor=reject_factor)
    R = np.zeros((3, 3, z.shape[1]))
    u2 = np.where(np.isfinite(u), u * u, 1.0)
    for i in range(3):
        R[i, i] = u2[i]
    return z, R


def channel_covariance(kin: KinematicSolution, noise_std) -> np.ndarray:
    """Covariance (12, 12) of one sample of the kinematic unknowns.

    Parameters
    ----------
    kin : KinematicSolution
    noise_std : float or ndarray, shape (M,)
        White-noise standard deviation of each channel, m/s^2.
    """
    s = np.broadcast_to(np.asarray(noise_std, float), (kin.sensitivity.shape[1],))
    return (kin.sensitivity * s * s) @ kin.sensitivity.T


def kalman_rate(kin: KinematicSolution, t: np.ndarray, noise_std, *, observation: str = "quadratic",
                initial=None, initial_std: float = 1e-3, lag: int = 1, gate_probability: float = 1e-4,
                passes: int = 3, bias_std=None, smooth: bool = False, reset_after: int = 5,
                offsets_prior=None, prior_samples=None) -> RateFilterResult:
    """Independent Kalman filter: integration as process, the array's quadratic terms as observation.

    Parameters
    ----------
    kin : KinematicSolution
        Output of :func:`~senscal.gfimu.solve_kinematics`.
    t : ndarray, shape (T,)
        Time, s.
    noise_std : float or ndarray, shape (M,)
        White-noise standard deviation of each channel, m/s^2.
    observation : {"quadratic", "sqrt", "differential"}
        ``"sqrt"`` (paper section 3.2) and ``"differential"`` (paper
        section 4): linear filter on ``w`` from that method, with a
        conditioning-aware covariance per sample.  ``"quadratic"`` (beyond
        the paper): extended Kalman filter whose measurement is the six
        quadratic terms ``w w^T - |w|^2 I`` themselves, with their exact
        covariance from the solve; no square root, no sign test, and the
        cross products keep every axis observable while any axis turns.
    initial : sequence of 3 floats, optional
        Angular velocity at ``t[0]`` (rad/s).  Linear filters without it
        start from their first observations (diffuse prior); the quadratic
        filter, whose measurement cannot tell ``w`` from ``-w``, starts at
        rest.
    initial_std : float
        Standard uncertainty of ``initial`` (or of the rest start), rad/s.
    lag : int
        Span of the differential observation in samples; with ``lag > 1``
        only every ``lag``-th sample is observed so that observation errors
        stay independent.
    gate_probability : float
        False-rejection probability of the innovation gate (chi-square on
        the normalised innovation squared); 0 disables gating.
    passes : int
        Maximum passes for the square-root observation: pass 1 takes the
        sign from the integration method as the paper does, later passes
        from the previous pass's filtered estimate (stops when no sign
        changes).
    bias_std : float or ndarray, shape (M,), optional
        Standard uncertainty of each channel's constant error (bias), m/s^2.
        With it the quadratic filter also estimates the constant errors
        these biases put into the angular acceleration and the six
        quadratic terms (nine random-constant states whose prior covariance
        is the biases' image through the solve), so that they neither drift
        the integration nor floor the estimate, and ``u_omega`` includes
        their remaining uncertainty.  Quadratic observation only.
    smooth : bool
        Offline: return the Rauch-Tung-Striebel fixed-interval smoother's
        estimate (every sample uses the whole record) instead of the causal
        filter's; with ``bias_std`` the smoother runs on the kinematics
        corrected by the filter's final constant-error estimates (their
        remaining uncertainty, ~1e-3 of the white-noise part, is left out of
        ``u_omega``).
    reset_after : int
        Quadratic observation: after this many consecutive gated samples the
        rate covariance is widened (x4 per further gated sample) until the
        filter accepts the measurements again (0: never; the filter then
        integrates on, which is the paper's behaviour).  Five false
        rejections in a row have probability ``gate_probability**5`` when
        the model holds, so the reset only acts on a real lock-out.
    offsets_prior : tuple (ndarray (9,), ndarray (9, 9)), optional
        With ``bias_std`` replaced: prior mean and covariance of the nine
        constant errors (e.g. measured on a rest segment), in
        :data:`~senscal.gfimu.layout.UNKNOWNS` order ``alpha_x`` ... ``W_yz``.
    prior_samples : ndarray of bool, shape (T,), optional
        Samples whose measurements made ``offsets_prior`` (the rest
        segment): the filter only predicts through them, so that their
        information is not counted twice.

    Returns
    -------
    RateFilterResult

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), section 3, eq. (10)-(17).
    """
    if observation not in OBSERVATIONS:
        raise InputError(f"observation must be one of {', '.join(OBSERVATIONS)}, got {observation!r}")
    if not 0 <= gate_probability < 1:
        raise InputError("gate_probability must be in [0, 1)")
    if not initial_std > 0:
        raise InputError("initial_std must be positive (rad/s)")
    t = np.asarray(t, float)
    C = channel_covariance(kin, noise_std)
    alpha = kin.angular_acceleration
    inc = rate_increments(alpha, t)
    u = np.zeros_like(inc)
    u[:, :-1] = inc[:, 1:]  # control of step k-1 drives the prediction of step k
    from senscal.io.recording import sample_rate_of

    dt = 1.0 / sample_rate_of(t)  # the rule of every job: the mean interval over the record
    Q = dt * dt * C[3:6, 3:6]
    if initial is None and observation != "quadratic":
        x0, P0 = np.zeros(3), np.eye(3) * 1e6
    else:
        x0 = np.zeros(3) if initial is None else np.asarray(initial, float).reshape(3)
        P0 = np.eye(3) * initial_std ** 2
    m = 6 if observation == "quadratic" else 3
    gate = float(chi2.isf(gate_probability, m)) if gate_probability > 0 else 0.0
    reset_after = int(reset_after)
    if reset_after < 0:
        raise InputError("reset_after must be a non-negative number of samples")
    if bias_std is not None or offsets_prior is not None:
        if observation != "quadratic":
            raise InputError("bias_std (constant-error states) needs the quadratic observation")
        res = _offsets_filter(kin, t, C, u, Q, x0, P0, gate, bias_std, offsets_prior, reset_after, prior_samples)
        if not smooth:
            return res
        # Smooth the 3-state EKF on the kinematics freed of the constant errors found over the record.
        c = res.offsets
        u_c = u.copy()
        u_c[:, :-1] -= np.diff(t) * c[:3, None]
        x, P, _, rej = quadratic_ekf(np.ascontiguousarray(kin.W - c[3:, None]), u_c, Q,
                                     np.linalg.inv(C[6:12, 6:12]), x0, P0, gate, reset_after)
        x, P = _smooth(x, P, u_c, Q, x0, P0)
        # The diagnostics (NIS, gating) stay the causal filter's: they judge the model, not the smoother.
        return replace(_result(x, P, res.gated, np.ones((6, x.shape[1]), bool), observation, 1, True),
                       offsets=res.offsets, u_offsets=res.u_offsets, nis=res.nis, innovations=res.innovations,
                       innovation_inv_cov=res.innovation_inv_cov)
    if observation == "quadratic":
        x, P, nis, rej = quadratic_ekf(np.ascontiguousarray(kin.W), u, Q, np.linalg.inv(C[6:12, 6:12]), x0, P0,
                                       gate, reset_after)
        if smooth:
            x, P = _smooth(x, P, u, Q, x0, P0)
        return replace(_result(x, P, rej, np.ones((6, x.shape[1]), bool), observation, 1, smooth), nis=nis)
    S = square_map()
    cov_sq = S @ C[6:9, 6:9] @ S.T
    squares = kin.squares
    if observation == "differential":
        z, R = differential_observation(squares, alpha, t, cov_sq, lag=lag)
        if lag > 1:
            keep = np.zeros(z.shape[1], bool)
            keep[lag::lag] = True
            z[:, ~keep] = np.nan
        x, P, _, rej = _filter(z, u, Q, R, x0, P0, gate)
        if smooth:
            x, P = _smooth(x, P, u, Q, x0, P0)
        return _result(x, P, rej, np.isfinite(z), observation, 1, smooth)
    ref = integration_rate(alpha, t, x0)
    z, R = sqrt_observation(squares, cov_sq, ref)
    x, P, _, rej = _filter(z, u, Q, R, x0, P0, gate)
    n_pass = 1
    while n_pass < passes:
        z_new, R = sqrt_observation(squares, cov_sq, x, x)
        same = np.array_equal(np.signbit(np.nan_to_num(z_new)), np.signbit(np.nan_to_num(z)))
        z = z_new
        x, P, _, rej = _filter(z, u, Q, R, x0, P0, gate)
        n_pass += 1
        if same:
            break
    if smooth:
        x, P = _smooth(x, P, u, Q, x0, P0)
    return _result(x, P, rej, np.isfinite(z), observation, n_pass, smooth)


def _offsets_filter(kin, t, C, u, Q, x0, P0, gate, bias_std, offsets_prior=None,
                    reset_after: int = 0, prior_samples=None) -> RateFilterResult:
    """The quadratic EKF with the nine constant errors of ``alpha`` and ``W`` as states."""
    x12 = np.zeros(12)
    x12[:3] = x0
    P12 = np.zeros((12, 12))
    P12[:3, :3] = P0
    if offsets_prior is not None:
        c0, Pc = (np.asarray(a, float) for a in offsets_prior)
        if c0.shape != (9,) or Pc.shape != (9, 9) or not (np.all(np.isfinite(c0)) and np.all(np.isfinite(Pc))):
            raise InputError("offsets_prior must be a finite mean (9,) and covariance (9, 9)")
        x12[3:] = c0
        P12[3:, 3:] = 0.5 * (Pc + Pc.T)
    else:
        b = np.broadcast_to(np.asarray(bias_std, float), (kin.sensitivity.shape[1],))
        if not np.all(np.isfinite(b)) or np.any(b < 0):
            raise InputError("bias_std must be non-negative numbers (m/s^2)")
        # The offsets are a linear image of the channel biases: their prior is that image's covariance.
        P12[3:, 3:] = channel_covariance(kin, np.maximum(b, 1e-12))[3:12, 3:12]
    dt = np.zeros(t.size)
    dt[1:] = np.diff(t)
    x, Pw, Pend, nis, rej, innov, sinv = quadratic_ekf_offsets(np.ascontiguousarray(kin.W), u, dt, Q, C[6:12, 6:12], x12, P12,
                                                  gate, reset_after, 4.0,
                                                  None if prior_samples is None else np.asarray(prior_samples, bool))
    res = _result(x[:3], Pw, rej, np.ones((6, x.shape[1]), bool), "quadratic", 1)
    return replace(res, offsets=x[3:, -1].copy(), u_offsets=np.sqrt(np.maximum(np.diag(Pend)[3:], 0.0)), nis=nis,
                   innovations=innov, innovation_inv_cov=sinv)


def _result(x, P, rej, ok, observation, passes, smoothed=False) -> RateFilterResult:
    u_om = np.sqrt(np.maximum(np.einsum("iik->ik", P), 0.0))
    return RateFilterResult(omega=x, u_omega=u_om, observation=observation,
                            n_observed=int(np.any(ok, axis=0).sum()), n_dropped=int((~ok).sum()),
                            n_gated=int(rej.sum()), passes=passes, smoothed=smoothed, gated=np.asarray(rej, bool))


def _smooth(x, P, u, Q, x0, P0):
    """RTS smoother of a filter with ``F = B = I`` (linear, or the EKF's linearisation) on the shared engine.

    The predictions are rebuilt from the filtered moments: ``x_pred[k] = x[k-1] + u[k-1]``,
    ``P_pred[k] = P[k-1] + Q`` (a gated step has filtered = predicted, which the smoother then passes through).
    """
    n = x.shape[1]
    xp = np.empty_like(x)
    xp[:, 0] = x0
    xp[:, 1:] = x[:, :-1] + u[:, :-1]
    Pp = np.empty_like(P)
    Pp[:, :, 0] = P0
    Pp[:, :, 1:] = P[:, :, :-1] + Q[:, :, None]
    eye = np.eye(3)
    model = StateSpaceModel(F=eye, H=eye, Q=Q, R=eye, B=eye, x0=x0, P0=P0)
    nan = np.full((3, n), np.nan)
    res = KalmanResult(x=x, P=P, x_pred=xp, P_pred=Pp, innovation=nan, innovation_cov=np.full((3, 3, n), np.nan),
                       normalized_innovation=nan, loglik=np.nan, rejected=np.zeros(n, bool))
    sm = rts_smoother(model, res)
    return sm.x, sm.P


def _filter(z, u, Q, R, x0, P0, gate):
    """The linear filters run on the shared engine: F = H = B = I, R per step."""
    eye = np.eye(3)
    model = StateSpaceModel(F=eye, H=eye, Q=Q, R=np.moveaxis(R, -1, 0), B=eye, x0=x0, P0=P0)
    res = kalman_filter(model, z, u, gate=gate if gate > 0 else None)
    return res.x, res.P, res.normalized_innovation, res.rejected
