"""Allan deviation of a rate signal: overlapping ADEV, modified ADEV, confidence intervals, noise identification.

Pure NumPy/SciPy (the usual ``allantools`` package is archived).  A rate
signal ``y`` sampled at ``fs`` is integrated once to phase
``x_i = sum_{k<i} y_k / fs`` (``N + 1`` phase points); every estimator below
is a fixed linear combination of phase samples, so each cluster time costs
O(N) (slices of one cumulative sum).

Estimators (Riley, *Handbook of Frequency Stability Analysis*, NIST SP 1065):

- overlapping Allan variance, ``tau = m / fs``::

    avar = sum_i (x[i+2m] - 2 x[i+m] + x[i])^2 / (2 tau^2 (Np - 2m))

- modified Allan variance::

    mvar = sum_j (sum_{i=j}^{j+m-1} (x[i+2m] - 2 x[i+m] + x[i]))^2 / (2 m^2 tau^2 (Np - 3m + 1))

Confidence intervals: ``sigma^2 * edf / sigma_hat^2`` is taken as chi-square
with ``edf`` equivalent degrees of freedom, from the *simple approximate
formulas* for the overlapping ADEV (Howe, Allan & Barnes 1981, as tabulated
by Riley, SP 1065 Table 8; Greenhall's exact algorithm is not implemented),
with ``Np`` phase points:

- white FM:        edf = (3(Np-1)/(2m) - 2(Np-2)/Np) * 4m^2/(4m^2+5)
- flicker FM:      edf = 2(Np-2)^2/(2.3Np-4.9) for m = 1, else 5Np^2/(4m(Np+3m))
- random-walk FM:  edf = (Np-2)/m * ((Np-1)^2 - 3m(Np-1) + 4m^2)/(Np-3)^2

``noise="auto"`` chooses per cluster time from the local log-log slope of the
estimate (below -1/4: white FM; above +1/4: random walk FM; between: flicker
FM).  The same formulas are used for the modified deviation, an
approximation (its exact edf differs, mostly for phase noise).

Noise identification (IEEE Std 952 conventions, two-sided PSD):

- angle/velocity random walk ``N``: the -1/2 slope line ``N / sqrt(tau)``
  read at tau = 1 s;
- bias instability ``B``: the minimum of the curve divided by
  ``sqrt(2 ln 2 / pi) = 0.664``;
- rate random walk ``K``: the +1/2 slope line ``K sqrt(tau / 3)`` read at
  tau = 3 s.

The two lines come from one weighted fit of the whole curve (see
:func:`identify_noise`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from senscal.errors import InputError, TooFewSamplesError

__all__ = ["AllanResult", "NoiseLevels", "allan_deviation", "edf_simple", "identify_noise", "FLICKER_FACTOR"]

FLICKER_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643: ADEV floor / B
MIN_CLUSTERS = 3
_NOISES = ("auto", "white", "flicker", "rw")


@dataclass(frozen=True)
class AllanResult:
    """Allan (or modified Allan) deviation of one rate signal.

    Attributes
    ----------
    taus : ndarray (M,)
        Cluster times [s].
    m : ndarray (M,) of int
        Cluster sizes in samples.
    dev : ndarray (M,)
        Deviation [signal unit].
    lower, upper : ndarray (M,)
        Confidence interval of ``dev`` at ``confidence``.
    confidence : float
        Two-sided level of the interval.
    n_clusters : ndarray (M,) of int
        Non-overlapping clusters of ``m`` samples in the record (``N // m``).
    n_terms : ndarray (M,) of int
        Terms of the (overlapping) sum.
    edf : ndarray (M,)
        Equivalent degrees of freedom.
    noise : tuple of str
        Noise type each edf assumes ("white", "flicker", "rw").
    kind : str
        "overlapping" or "modified".
    fs : float
    n_samples : int
    warnings : tuple of str
    """

    taus: np.ndarray
    m: np.ndarray
    dev: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    confidence: float
    n_clusters: np.ndarray
    n_terms: np.ndarray
    edf: np.ndarray
    noise: tuple
    kind: str
    fs: float
    n_samples: int
    warnings: tuple = field(default=())

    @property
    def adev(self) -> np.ndarray:
        """Alias of ``dev``."""
        return self.dev


@dataclass(frozen=True)
class NoiseLevels:
    """Noise coefficients read off an Allan deviation (None where the curve shows no such region).

    ``N`` [unit*sqrt(s)] (angle/velocity random walk; also the white noise
    density, unit/sqrt(Hz)), ``B`` [unit] (bias instability), ``K``
    [unit/sqrt(s)] (rate random walk), each with its standard uncertainty
    ``u_*`` and ``tau_min`` [s], where the curve has its minimum.
    """

    N: float | None
    u_N: float | None
    B: float
    u_B: float
    K: float | None
    u_K: float | None
    tau_min: float


def edf_simple(n_phase: int, m: np.ndarray | int, noise: str) -> np.ndarray:
    """Simple approximate edf of the overlapping Allan variance (see the module docstring).

    Parameters
    ----------
    n_phase : int
        Phase points (samples + 1).
    m : int or ndarray
        Cluster sizes.
    noise : {"white", "flicker", "rw"}
    """
    n = float(n_phase)
    m = np.asarray(m, dtype=float)
    if noise == "white":
        e = (3 * (n - 1) / (2 * m) - 2 * (n - 2) / n) * 4 * m ** 2 / (4 * m ** 2 + 5)
    elif noise == "flicker":
        e = np.where(m == 1, 2 * (n - 2) ** 2 / (2.3 * n - 4.9), 5 * n ** 2 / (4 * m * (n + 3 * m)))
    elif noise == "rw":
        e = (n - 2) / m * ((n - 1) ** 2 - 3 * m * (n - 1) + 4 * m ** 2) / (n - 3) ** 2
    else:
        raise InputError(f"noise must be white, flicker or rw, got {noise!r}")
    return np.maximum(e, 1.0)  # the formulas fail for clusters near the record length; one degree is the floor


def _octave_m(n: int) -> np.ndarray:
    m, out = 1, []
    while n // m >= MIN_CLUSTERS:
        out.append(m)
        m *= 2
    return np.asarray(out, dtype=int)


def allan_deviation(y: Sequence[float] | np.ndarray, fs: float, taus: Sequence[float] | None = None, *,
                    kind: str = "overlapping", confidence: float = 0.683, noise: str = "auto") -> AllanResult:
    """Overlapping (or modified) Allan deviation of a rate signal with chi-square confidence intervals.

    Parameters
    ----------
    y : array_like (N,)
        Rate samples (gyro rate, sensor reading) at a constant rate.
    fs : float
        Sample rate [Hz].
    taus : sequence of float, optional
        Cluster times [s] (rounded to whole samples); default octave-spaced
        ``m = 1, 2, 4, ...`` while at least 3 clusters fit the record.
    kind : {"overlapping", "modified"}
    confidence : float
        Two-sided level of the intervals (0.683 ~ one sigma).
    noise : {"auto", "white", "flicker", "rw"}
        Noise type for the edf; "auto" per tau from the local slope.

    Returns
    -------
    AllanResult

    Raises
    ------
    InputError
        Bad arguments or non-finite samples.
    TooFewSamplesError
        Fewer than 3 clusters of the smallest cluster time fit the record.
    """
    from scipy.stats import chi2

    y = np.asarray(y, dtype=float)
    if y.ndim != 1:
        raise InputError(f"the signal must be one channel (1-D), got shape {y.shape}")
    if not (isinstance(fs, (int, float)) and math.isfinite(fs) and fs > 0):
        raise InputError(f"the sample rate must be a positive number, got {fs!r}")
    if kind not in ("overlapping", "modified"):
        raise InputError(f"kind must be overlapping or modified, got {kind!r}")
    if noise not in _NOISES:
        raise InputError(f"noise must be one of {', '.join(_NOISES)}, got {noise!r}")
    if not 0 < confidence < 1:
        raise InputError(f"confidence must lie between 0 and 1, got {confidence!r}")
    if not np.isfinite(y).all():
        i = int(np.flatnonzero(~np.isfinite(y))[0])
        raise InputError(f"the signal has a non-finite value at sample {i}; remove or interpolate it first")
    n = y.size
    warnings: list[str] = []
    if taus is None:
        m = _octave_m(n)
        if m.size == 0:
            raise TooFewSamplesError(f"{n} samples are too few for an Allan deviation: "
                                     f"at least {MIN_CLUSTERS} are needed")
    else:
        t = np.asarray(taus, dtype=float).ravel()
        if t.size == 0 or not np.isfinite(t).all() or (t <= 0).any():
            raise InputError("cluster times must be positive finite numbers")
        m = np.unique(np.maximum(1, np.rint(t * fs)).astype(int))
        if n // m[0] < MIN_CLUSTERS:
            raise TooFewSamplesError(
                f"the record ({n} samples, {n / fs:g} s) holds {n // m[0]} cluster(s) of the smallest cluster time "
                f"{m[0] / fs:g} s; at least {MIN_CLUSTERS} are needed")
        keep = n // m >= MIN_CLUSTERS
        if not keep.all():
            warnings.append(f"allan-taus-dropped: cluster times above {m[keep][-1] / fs:g} s left out "
                            f"(fewer than {MIN_CLUSTERS} clusters in the record)")
        m = m[keep]
    if kind == "modified":
        m = m[n + 1 - 3 * m + 1 >= 1]
    tau0 = 1.0 / fs
    # Phase relative to the mean rate keeps the cumulative sums small (ADEV is blind to a constant rate).
    x = np.concatenate(([0.0], np.cumsum(y - y.mean()))) * tau0
    npts = x.size
    dev = np.empty(m.size)
    terms = np.empty(m.size, dtype=int)
    for k, mk in enumerate(m):
        d = x[2 * mk:] - 2 * x[mk:-mk] + x[:-2 * mk]  # second differences, Np - 2m of them
        tau = mk * tau0
        if kind == "overlapping":
            terms[k] = d.size
            dev[k] = math.sqrt(np.dot(d, d) / (2 * tau * tau * d.size))
        else:
            c = np.concatenate(([0.0], np.cumsum(d)))
            s = c[mk:] - c[:-mk]  # sums of m consecutive second differences, Np - 3m + 1 of them
            terms[k] = s.size
            dev[k] = math.sqrt(np.dot(s, s) / (2 * mk * mk * tau * tau * s.size))
    taus_out = m * tau0
    if noise == "auto":
        types = _noise_from_slope(taus_out, dev)
    else:
        types = (noise,) * m.size
    edf = np.array([float(edf_simple(npts, mk, t)) for mk, t in zip(m, types)])
    a = (1.0 - confidence) / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        lower = dev * np.sqrt(edf / chi2.ppf(1 - a, edf))
        upper = dev * np.sqrt(edf / chi2.ppf(a, edf))
    return AllanResult(taus=taus_out, m=m, dev=dev, lower=lower, upper=upper, confidence=float(confidence),
                       n_clusters=n // m, n_terms=terms, edf=edf, noise=tuple(types), kind=kind, fs=float(fs),
                       n_samples=int(n), warnings=tuple(warnings))


def _local_slopes(taus: np.ndarray, dev: np.ndarray) -> np.ndarray:
    """Log-log slope at each point (central differences; one-sided at the ends)."""
    if taus.size < 2:
        return np.full(taus.size, -0.5)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.gradient(np.log(np.maximum(dev, 1e-300)), np.log(taus))


def _noise_from_slope(taus: np.ndarray, dev: np.ndarray) -> tuple:
    s = _local_slopes(taus, dev)
    return tuple("white" if v < -0.25 else ("rw" if v > 0.25 else "flicker") for v in s)


def _half_width(res: AllanResult, i: int) -> float:
    """Standard uncertainty of dev[i] from its interval (half-width scaled to one sigma)."""
    from scipy.stats import norm

    z = norm.ppf(0.5 + res.confidence / 2)
    return float((res.upper[i] - res.lower[i]) / (2 * z))


def identify_noise(res: AllanResult) -> NoiseLevels:
    """Read N (tau = 1 s on the -1/2 line), B (minimum / 0.664) and K (tau = 3 s on the +1/2 line) off a curve.

    N and K come from one fit of the Allan *variance* to
    ``N^2 / tau + C + K^2 tau / 3`` over all cluster times (non-negative
    least squares, each point weighted by its chi-square variance
    ``2 avar^2 / edf`` with avar from the fitted model, iterated), so the white noise does not bias K upwards where the
    two meet, nor the random walk N.  The standard uncertainty of each is
    the relative one of the most precise point (from its confidence
    interval) where that term is at least half the variance: a
    conservative figure, since the points the fit pools are correlated.  A coefficient the fit puts at zero is
    reported as None.  B is the minimum of the curve over 0.664 with the
    uncertainty of that point's interval.
    """
    from scipy.optimize import nnls

    taus, dev, edf = res.taus, res.dev, res.edf
    ok = np.isfinite(dev) & (dev > 0)
    t, v, e = taus[ok], dev[ok] ** 2, edf[ok]
    basis = np.column_stack([1.0 / t, np.ones_like(t), t / 3.0])
    model = v
    for _ in range(5):  # weights from the model, not the data: data weights favour the low estimates
        w = np.sqrt(e / 2.0) / model  # 1 / sd of each avar
        coef, _ = nnls(basis * w[:, None], v * w)
        model = np.maximum(basis @ coef, 1e-300)
    active = coef > 0
    model = basis @ coef
    rel = np.array([_half_width(res, i) for i in np.flatnonzero(ok)]) / dev[ok]  # relative u of each dev

    def level(j: int) -> tuple[float | None, float | None]:
        if not active[j]:
            return None, None
        value = math.sqrt(coef[j])
        dom = basis[:, j] * coef[j] >= 0.5 * model  # where this term is at least half the variance
        r = rel[dom].min() if dom.any() else rel[np.argmax(basis[:, j] * coef[j] / model)]
        return value, float(value * r)

    n_hat, u_n = level(0)
    k_hat, u_k = level(2)
    imin = int(np.nanargmin(np.where(ok, dev, np.nan)))
    b = float(dev[imin] / FLICKER_FACTOR)
    u_b = _half_width(res, imin) / FLICKER_FACTOR
    return NoiseLevels(N=n_hat, u_N=u_n, B=b, u_B=float(u_b), K=k_hat, u_K=u_k, tau_min=float(taus[imin]))
