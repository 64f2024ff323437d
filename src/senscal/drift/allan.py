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

__all__ = ["AllanResult", "NoiseLevels", "allan_deviation", "edf_simple", "identify_noise", "FLICKER_FACTOR",
           "drift_levels_from_allan"]

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
        raise InputError(f"the signal has a non-finite value in data row {i + 1}; remove or interpolate it first")
    peak = float(np.max(np.abs(y))) if y.size else 0.0
    if peak > MAX_ABS_VALUE:
        # The variance squares differences of cluster means: beyond ~1e150 they overflow to inf and the
        # curve (and the noise fit on it) is empty.
        raise InputError(f"the signal reaches {peak:.3g}; the Allan variance squares it and overflows beyond "
                         f"{MAX_ABS_VALUE:.0e}: rescale the channel (another unit prefix) or check the file")
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


#: Largest magnitude of a sample the Allan variance can square without overflow (with margin for sums).
MAX_ABS_VALUE = 1e150


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


#: Peak Allan deviation of a first-order Gauss-Markov process over its
#: stationary std (reached near tau = 1.89 correlation times).
_GM_PEAK = 0.618


def _white_std(res: AllanResult, lev: NoiseLevels) -> tuple[float, float]:
    """Per-sample white-noise std [unit] and its relative u: N sqrt(fs), else the shortest-tau deviation."""
    if lev.N is not None:
        return float(lev.N * math.sqrt(res.fs)), float(lev.u_N / lev.N)
    return float(res.dev[0]), _half_width(res, 0) / float(res.dev[0])


def drift_levels_from_allan(setup, y: np.ndarray, t: np.ndarray, *, with_u: bool = False) -> dict:
    """Starting noise levels of a drift set-up from Allan deviations (``--levels-from-allan``).

    The Allan identification reads white noise ``N``, bias instability
    ``B`` and rate random walk ``K`` off a signal whose true value does not
    move.  A drift record's quantity does move, so each curve is taken where
    the quantity cancels:

    - ``known`` quantity: each channel itself;
    - otherwise: each biased channel minus the reference (the mean of the
      trusted channels, else of the other channels), whose ``K`` is the
      bias's random-walk rate; the white noise of the difference is split
      between the channels by the three-cornered hat when there are three
      or more channels, equally otherwise; the quantity's random-walk rate
      is ``K`` of the reference (trusted channels only).

    Per-sample noise std = ``N sqrt(fs)``; random-walk bias rate = ``K``
    [unit/sqrt(s)]; a Gauss-Markov bias's std = ``0.664 B / 0.618`` (its
    Allan peak).  Ramp slopes and covariate coefficients are not seen by an
    Allan curve and are left out (the maximum-likelihood search starts them
    from its own rule).

    Parameters
    ----------
    setup : DriftSetup
    y : ndarray, (m, T)
        Measurements of ``setup.channels`` [unit]; no NaN.
    t : ndarray, (T,)
        Time [s], about uniform (the median interval is taken).
    with_u : bool
        Also return each level's standard uncertainty (from the Allan
        identification's; the three-cornered hat's and the equal split's
        are the difference curves' relative ones).

    Returns
    -------
    dict of str to float, or of str to (value, u)
        A subset of ``setup.level_names()``.

    Raises
    ------
    InputError
        NaN in the data, or fewer than 3 clusters of one sample.
    """
    y = np.asarray(y, dtype=float)
    t = np.asarray(t, dtype=float)
    if not np.isfinite(y).all():
        raise InputError("--levels-from-allan needs gap-free channels (an Allan deviation has no missing samples); "
                         "interpolate the gaps or drop the option")
    from senscal.io.recording import sample_rate_of

    fs = sample_rate_of(t)  # the rule of every job: the mean rate over the record
    chans = list(setup.channels)
    idx = {c: i for i, c in enumerate(chans)}

    def curve(x):
        res = allan_deviation(x - x.mean(), fs)
        return res, identify_noise(res)

    out: dict[str, float] = {}
    rel: dict[str, float] = {}  # relative standard uncertainty of each level
    rates: dict[str, tuple[float | None, float | None]] = {}
    instab: dict[str, float] = {}
    if setup.signal.kind == "known":
        for c in chans:
            res, lev = curve(y[idx[c]])
            out[f"{c}_noise_std"], rel[f"{c}_noise_std"] = _white_std(res, lev)
            rates[c], instab[c] = (lev.K, lev.u_K), lev.B
    else:
        trusted = [c for c in setup.trusted if c in idx]
        white_diff: dict[tuple[str, str], float] = {}
        for c in setup.biased_channels:
            others = trusted or [o for o in chans if o != c]
            ref = y[[idx[o] for o in others]].mean(axis=0)
            res, lev = curve(y[idx[c]] - ref)
            w, r = _white_std(res, lev)
            white_diff[(c, "ref")] = (w**2, r)
            rates[c], instab[c] = (lev.K, lev.u_K), lev.B
        var: dict[str, float] = {}
        vrel: dict[str, float] = {}
        if len(chans) >= 3:
            # Three-cornered hat on every pair: var_i = mean over (j, k) of (v_ij + v_ik - v_jk) / 2.
            pair = {}
            for a in range(len(chans)):
                for b in range(a + 1, len(chans)):
                    res, lev = curve(y[a] - y[b])
                    w, r = _white_std(res, lev)
                    pair[(a, b)] = pair[(b, a)] = w**2
                    vrel[chans[a]] = max(vrel.get(chans[a], 0.0), r)
                    vrel[chans[b]] = max(vrel.get(chans[b], 0.0), r)
            for i, c in enumerate(chans):
                est = [(pair[(i, j)] + pair[(i, k)] - pair[(j, k)]) / 2
                       for j in range(len(chans)) for k in range(j + 1, len(chans)) if i not in (j, k)]
                var[c] = max(float(np.mean(est)), 0.0)
        else:
            v = next(iter(white_diff.values()), None)
            if v is None:
                res, lev = curve(np.diff(y, axis=0)[0] if len(chans) > 1 else y[0])
                w, r = _white_std(res, lev)
                v = (w**2, r)
            for c in chans:
                var[c], vrel[c] = v[0] / (2.0 if len(chans) > 1 else 1.0), v[1]
        floor = 1e-6 * max(max(var.values()), 1e-300)
        for c in chans:
            out[f"{c}_noise_std"] = math.sqrt(max(var[c], floor))
            rel[f"{c}_noise_std"] = vrel[c]
        if setup.signal.level_name == "signal_rate_std" and trusted:
            res, lev = curve(y[[idx[c] for c in trusted]].mean(axis=0))
            if lev.K is not None:
                out["signal_rate_std"] = float(lev.K)
                rel["signal_rate_std"] = float(lev.u_K / lev.K)
    for b in setup.biases:
        if b.covariate is not None or b.level is not None:
            continue
        if b.dynamics == "random_walk":
            # No +1/2 region: the bias did not wander over the record; a tiny rate, not zero, so the search can move it.
            k, u_k = rates.get(b.channel, (None, None))
            if k is not None:
                out[b.level_name], rel[b.level_name] = float(k), float(u_k / k)
            else:
                out[b.level_name], rel[b.level_name] = 1e-3 * out[f"{b.channel}_noise_std"] * math.sqrt(fs), 1.0
        elif b.dynamics == "gauss_markov":
            out[b.level_name] = float(FLICKER_FACTOR * instab[b.channel] / _GM_PEAK)
            rel[b.level_name] = 1.0  # the peak-to-std factor assumes one time constant: a rough start only
    names = setup.level_names()
    if with_u:
        return {k: (v, v * rel[k]) for k, v in out.items() if k in names}
    return {k: v for k, v in out.items() if k in names}
