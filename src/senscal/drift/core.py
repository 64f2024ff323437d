"""Slow-drift bias correction with the augmented Kalman filter (patent steps a-c)."""

from __future__ import annotations

import dataclasses
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy.special import chdtrc

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.drift._blas import one_blas_thread
from senscal.drift.adequacy import InnovationCheck, MomentLevels, innovation_checks, moment_levels
from senscal.drift.detect import cusum, cusum_threshold
from senscal.drift.estimate import NoiseParameter, estimate_levels
from senscal.drift.likelihood import LevelLikelihood
from senscal.drift.model import Bias, DriftSetup, _uniform_dt, augmented_model, check_observable
from senscal.errors import DataError, InputError, TooFewSamplesError
from senscal.kalman import fixed_lag_smoother, kalman_filter, rts_smoother

__all__ = ["DriftResult", "correct_drift", "drift_prior", "channel_bias", "DEFAULT_FALSE_ALARM_RATE"]

#: Default false-alarm rate of the drift-onset detector [alarms per hour per channel].
DEFAULT_FALSE_ALARM_RATE = 1e-4

#: AIC difference above which an alternative model is named as better:
#: zero, i.e. the minimum-AIC model (Akaike's rule).  On the model's own data
#: the alternatives lose by 6-20 (random-walk vs ramp bias, 600 samples), so
#: the warning is rare there; a real ramp or a wrong time constant wins by
#: more.
_AIC_MARGIN = 0.0
#: AIC difference above which a model the job does not use is *named*
#: (``better-model``): its Akaike weight against the model used beats
#: 0.95, exp(-d/2) / (1 + exp(-d/2)) < 0.05, i.e. d > 2 ln 19 = 5.89
#: (Burnham & Anderson 2002, sec. 2.9: within 4-7 AIC units a model still
#: has "considerably less" but real support, so the data do not yet
#: favour the other one at 95 %).  With a margin of 0 the name fired on a
#: free covariate lag in 31 % of lag-free records (100 seeds).
_NAME_MARGIN = 2.0 * math.log(19.0)


@dataclass(frozen=True)
class DriftResult(ResultMixin):
    """Bias estimates, corrected measurements and drift onsets.

    Arrays have time on the last axis; rows follow ``channels`` (the
    channels with a bias, i.e. the corrected ones) or ``state_names``.

    Attributes
    ----------
    t : ndarray, (T,)
        Time [s].
    channels : tuple of str
        Corrected channels.
    corrected : ndarray, (mc, T)
        ``y - b_hat`` [unit] (NaN where the measurement was missing).
    bias : ndarray, (mc, T)
        Total estimated bias of each channel ``b_hat_t`` [unit].
    bias_std : ndarray, (mc, T)
        Its standard deviation (k=1) [unit].
    state_names : tuple of str
        ``signal``, ``B_bias``, ``C_temperature_coefficient`` ...
    state_channels : tuple of str or None
        The channel each state biases (None for signal states).
    state, state_std : ndarray, (n, T)
        Estimated augmented state and its standard deviation.
    onset_t, alarm_t : dict of str to float or None
        Per corrected channel: estimated drift start and alarm time [s] of
        the CUSUM detector, None when no drift was detected.
    noise : tuple of NoiseParameter
        Noise levels used (given or estimated, with uncertainties).
    loglik : float
        Log-likelihood of the data under the final model [nats].
    method : str
        ``filter``, ``window`` (fixed-lag, ``window`` samples) or ``smoother``.
    window : int or None
        Window (lag) length in samples.
    false_alarm_rate : float
        Detector false-alarm rate [1/h per channel].
    cusum_threshold : float
        Detector threshold h [standard deviations].
    check : InnovationCheck or None
        Scale and whiteness tests of the final model's innovations.
    comparison : tuple of dict
        The model asked for first (``asked``), then each alternative fitted:
        ``model``, ``loglik`` [nats], ``n_levels``, ``aic``, ``nested``.
    warnings : tuple of str
        Named warnings (``degenerate-noise-levels``, ``model-inadequate``,
        ``better-model``, ``covariate-reference-defaulted``).
    setup : DriftSetup
        The model the numbers come from.
    selected : str or None
        The alternative adopted instead of the model asked for (its label,
        e.g. ``--noise ar1``), None when the model asked for was kept.
    tau_average : dict or None
        A Gauss-Markov quantity whose time constant was not given as known:
        ``asked`` and ``most_likely`` [s], the time constants averaged over
        ``taus`` [s] with their ``weights`` (profile likelihood, flat prior
        on ln tau) and ``loglik`` [nats], and ``applied`` (False when the
        model used is not of the averaged family, e.g. a random walk chosen
        instead).  None otherwise.
    """

    t: np.ndarray
    channels: tuple[str, ...]
    corrected: np.ndarray
    bias: np.ndarray
    bias_std: np.ndarray
    state_names: tuple[str, ...]
    state_channels: tuple
    state: np.ndarray
    state_std: np.ndarray
    onset_t: dict
    alarm_t: dict
    noise: tuple[NoiseParameter, ...]
    loglik: float
    method: str
    window: int | None
    false_alarm_rate: float
    cusum_threshold: float
    check: InnovationCheck | None = None
    comparison: tuple = ()
    warnings: tuple[str, ...] = ()
    setup: Any = None
    selected: str | None = None
    tau_average: dict | None = None

    def final(self, name: str) -> tuple[float, float]:
        """Last estimate of a state and its standard deviation."""
        i = self.state_names.index(name)
        return float(self.state[i, -1]), float(self.state_std[i, -1])

    def summary(self) -> dict[str, Any]:
        """The JSON document of ``senscal drift`` (CLI contract).

        ``channels``: per corrected channel the final ``bias`` and
        ``bias_std``, ``onset_t`` / ``alarm_t`` (or null), and each bias
        term's final ``value`` / ``std``; ``noise``: every noise level with
        ``value``, ``std`` (null when given or at a bound), ``estimated``.
        """
        chans = {}
        for i, c in enumerate(self.channels):
            terms = {s: {"value": float(self.state[j, -1]), "std": float(self.state_std[j, -1])}
                     for j, s in enumerate(self.state_names) if self.state_channels[j] == c}
            chans[c] = {"bias": float(self.bias[i, -1]), "bias_std": float(self.bias_std[i, -1]),
                        "onset_t": self.onset_t.get(c), "alarm_t": self.alarm_t.get(c), "terms": terms}
        return {
            "method": self.method, "window": self.window, "n_samples": int(self.t.size),
            "channels": chans,
            "noise": {p.name: {"value": p.value, "std": p.std, "estimated": p.estimated, "at_bound": p.at_bound}
                      for p in self.noise},
            "loglik": self.loglik,
            "detector": {"false_alarm_rate_per_hour": self.false_alarm_rate, "cusum_threshold": self.cusum_threshold},
            "model_check": None if self.check is None else self.check.to_dict(),
            "model_comparison": [dict(c) for c in self.comparison],
            "model_selected": self.selected,
            "signal_tau_average": None if self.tau_average is None else dict(self.tau_average),
            "warnings": list(self.warnings),
        }


def _robust_std(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    if x.size < 2:
        return 0.0
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def _starting_levels(setup: DriftSetup, y: np.ndarray, dt: float, duration: float,
                     cov: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Data-driven starting values of every level (robust first differences)."""
    scale = max(float(np.nanstd(y)), 1e-300)
    start: dict[str, float] = {}
    for i, c in enumerate(setup.channels):
        # White noise doubles in variance under differencing.
        s = _robust_std(np.diff(y[i])) / np.sqrt(2.0)
        start[f"{c}_noise_std"] = s if s > 0 else 1e-3 * scale
    noise = min(start.values())
    if setup.signal.level_name == "signal_rate_std":
        mean_y = np.nanmean(y, axis=0)
        s = _robust_std(np.diff(mean_y))
        start["signal_rate_std"] = max(s, 0.1 * noise) / np.sqrt(dt)
    elif setup.signal.level_name == "signal_std":
        start["signal_std"] = scale
    for b in setup.biases:
        unit = 1.0
        if b.covariate is not None:
            unit = 1.0 / max(float(np.std(cov[b.covariate])), 1e-300)
        if b.dynamics == "random_walk":
            start[b.level_name] = 0.1 * noise * unit / np.sqrt(duration)
        else:
            start[b.level_name] = noise * unit
        if b.lag_name:
            # A sensor's thermal lag: seconds to minutes; the search spans 1e-7 to 1e4 times this.
            start[b.lag_name] = 10.0 * dt
    for c in setup.ar_noise:
        # Coloured noise as large as the white noise, correlated over a few samples.
        start[f"{c}_noise_ar_std"] = start[f"{c}_noise_std"]
        start[f"{c}_noise_ar_tau"] = 3.0 * dt
    return start


def _moment_levels_start(setup: DriftSetup, y: np.ndarray, dt: float, duration: float,
                         cov: Mapping[str, np.ndarray], mom: MomentLevels) -> dict[str, float]:
    """Starting levels from differenced autocovariances (:func:`moment_levels`).

    Unlike the spread of the increments, the lag-one autocovariance of the
    differences sees only the white noise, however large the quantity's own
    steps are; the cross-covariance of two channels' differences sees only
    the quantity.  Levels the moments cannot give keep the robust
    first-difference values of :func:`_starting_levels`.
    """
    start = _starting_levels(setup, y, dt, duration, cov)
    idx = {c: i for i, c in enumerate(setup.channels)}
    for c, i in idx.items():
        r = mom.noise_var[i]
        if np.isfinite(r) and r > 0:
            start[f"{c}_noise_std"] = float(np.sqrt(r))
    floor = 1e-4 * min(start[f"{c}_noise_std"] for c in setup.channels) ** 2
    common = mom.common_var if np.isfinite(mom.common_var) and setup.signal.kind != "known" else 0.0
    if setup.signal.level_name == "signal_rate_std":
        q = common if len(setup.channels) > 1 else float(np.nanmin(mom.own_var))
        start["signal_rate_std"] = float(np.sqrt(max(q, floor) / dt))
    for b in setup.biases:
        if b.covariate is not None or b.dynamics == "gauss_markov":
            continue
        q = max(float(mom.own_var[idx[b.channel]]) - common, floor)
        rate = float(np.sqrt(q / dt))
        # A ramp whose slope wanders at a moves the bias by ~a D^1.5 / sqrt(3)
        # over D seconds; match the random walk's r sqrt(D).
        start[b.level_name] = rate if b.dynamics == "random_walk" else rate * np.sqrt(3.0) / duration
    return start


def _degenerate(setup: DriftSetup, noise: Sequence[NoiseParameter], mom: MomentLevels) -> list[str]:
    """Named warning when the ML white-noise levels collapsed.

    A channel's noise variance is resolved by the moments when its lag-one
    estimate exceeds five standard errors; a maximum-likelihood variance
    below a tenth of it (or at the search's lower bound) means the random
    walks have absorbed the sensor noise: the filter then copies the
    measurements into the states and its stated uncertainties are far too
    small.
    """
    est = {p.name: p for p in noise if p.estimated}
    bad = []
    for i, c in enumerate(setup.channels):
        p = est.get(f"{c}_noise_std")
        r, se = mom.noise_var[i], mom.noise_var_se[i]
        if p is None or not (np.isfinite(r) and r > 5 * se):
            continue
        if p.value**2 < 0.1 * r or (p.at_bound and p.value**2 < r):
            bad.append(f"{c} {p.value:.3g} (differences show {np.sqrt(r):.3g})")
    if not bad:
        return []
    return [named("degenerate-noise-levels", (
        f"the maximum-likelihood white-noise std collapsed for {'; '.join(bad)}: the random walks absorb the "
        "sensor noise and the stated uncertainties are too small; give the noise levels (noise_std in a model "
        "file) or a better model of the quantity (--signal gauss_markov, --bias-dynamics ramp)"))]


def _alternatives(setup: DriftSetup) -> list[tuple[str, DriftSetup, bool]]:
    """The other offered models: ``(label, set-up, nested)``.

    Nested extensions of the model asked for (coloured AR(1) measurement
    noise on every channel; a first-order lag on each covariate) contain it
    as a special case; coloured noise is chosen whenever AIC prefers it, the
    swaps (signal model or its tau, random-walk <-> ramp biases) and the lag
    replace the model asked for only when its innovations reject it (see
    :func:`correct_drift`), and otherwise are named by ``better-model``.
    """
    out = []
    if setup.signal.kind == "gauss_markov":
        out.append(("--signal random_walk", dataclasses.replace(setup, signal=dataclasses.replace(
            setup.signal, kind="random_walk", tau=None, mean=0.0, level=None, tau_known=False)), False))
        # A time constant a decade off either way: enough to show that the
        # one given is not where the likelihood is.
        for f in (0.1, 10.0):
            tau = setup.signal.tau * f
            out.append((f"--signal-tau {tau:.4g}", dataclasses.replace(setup, signal=dataclasses.replace(
                setup.signal, tau=tau, level=None)), False))
    swap = {"random_walk": "ramp", "ramp": "random_walk"}
    add = [b for b in setup.biases if b.covariate is None and b.dynamics in swap and b.level is None]
    if add:
        new = swap[add[0].dynamics]
        biases = tuple(dataclasses.replace(b, dynamics=new) if b in add else b for b in setup.biases)
        out.append((f"--bias-dynamics {new}", dataclasses.replace(setup, biases=biases), False))
    if not setup.ar_noise:
        out.append(("--noise ar1", dataclasses.replace(setup, ar_noise=tuple(setup.channels)), True))
    lag = [b for b in setup.biases if b.covariate is not None and not b.fit_lag and b.lag is None]  # given: known
    if lag:
        # Offered like a swap, not taken on AIC alone: with one sensor a free
        # lag also absorbs other misfits (a wrong signal tau: the lag model won
        # in 6 of 8 records and moved the coefficient by 2-8 u).
        biases = tuple(dataclasses.replace(b, fit_lag=True) if b in lag else b for b in setup.biases)
        out.append(("--covariate-lag", dataclasses.replace(setup, biases=biases), False))
    return out


def _compare_models(setup: DriftSetup, y: np.ndarray, t: np.ndarray, covariates, loglik: float,
                    n_levels: int) -> tuple[tuple[dict, ...], dict]:
    """Maximised log-likelihood and AIC of the model asked for and its alternatives.

    Every model is fitted to the same measurements, so the likelihoods are
    comparable; AIC = 2 k - 2 ln L with k the estimated noise levels.

    Returns
    -------
    rows : tuple of dict
        ``model``, ``loglik``, ``n_levels``, ``aic``, ``nested`` (the asked
        model first, labelled ``asked``).
    setups : dict
        Label -> DriftSetup of each alternative fitted.
    """
    rows = [{"model": "asked", "loglik": loglik, "n_levels": n_levels, "aic": 2 * n_levels - 2 * loglik,
             "nested": True}]
    setups = {}
    for label, alt, nested in _alternatives(setup):
        try:
            noise, ll = correct_drift(alt, y, t, covariates, compare=False, _fit_only=True)
        except Exception:  # an alternative that cannot be fitted is simply not offered
            continue
        k = sum(p.estimated for p in noise)
        rows.append({"model": label, "loglik": ll, "n_levels": k, "aic": 2 * k - 2 * ll, "nested": nested})
        setups[label] = alt
    return tuple(rows), setups


#: Level of the likelihood-ratio test that names coloured noise (:func:`_colour_warning`).
_COLOUR_ALPHA = 0.05


def _colour_warning(asked: Mapping[str, Any], used: Mapping[str, Any]) -> list[str]:
    """Named warning when the model used has coloured noise that the record does show.

    With AR(1) noise on a biased channel the record sees the bias rate only
    through the lowest frequencies, which the coloured noise shares; the
    rate's likelihood is then far from normal (its ML value is zero in about
    one record in eight at rho 0.8 on 600 samples) and the final bias's u,
    even with the rate integrated over its likelihood, covered 91.5 % (200
    seeds), below the 93 % the rule allows.  So the colour is named when the
    coloured-noise model is used and a likelihood-ratio test rejects white
    noise at :data:`_COLOUR_ALPHA` (chi-square with as many dof as the
    levels the AR terms add: conservative, as some sit on a boundary).

    Returns
    -------
    list of str
        ``coloured-noise`` or nothing.
    """
    if used.get("model") != "--noise ar1":
        return []
    dof = int(used["n_levels"] - asked["n_levels"])
    lr = 2.0 * (float(used["loglik"]) - float(asked["loglik"]))
    if dof < 1 or not lr > 0 or not float(chdtrc(dof, lr)) < _COLOUR_ALPHA:
        return []
    return [named("coloured-noise", (
        f"the measurement noise is coloured (AR(1) model used; likelihood ratio {lr:.1f} against white noise, "
        f"{dof} dof, p = {float(chdtrc(dof, lr)):.1g}): the bias rate is then seen only through the lowest "
        "frequencies and the stated u of the final bias may be too small (91.5 % coverage at rho 0.8); use a "
        "longer record, a trusted reference with white noise, or give the bias rate (a model file)"))]


def _lag_warnings(noise: Sequence[NoiseParameter]) -> list[str]:
    """Named warning when an estimated covariate lag is not determined by the record.

    The coefficient's u holds the lag's uncertainty only where the lag is
    known to better than a factor e; a lag at its search bound, or spread
    wider, leaves the coefficient depending on a time constant the data do
    not fix (a lag comparable to the record trades with the quantity).
    """
    bad = [f"{p.name[:-4]} (lag {p.value:.3g} s{', at the search bound' if p.at_bound else ''})"
           for p in noise if p.estimated and p.name.endswith("_lag")
           and (p.at_bound or p.std is None or p.std > p.value)]
    if not bad:
        return []
    return [named("covariate-lag-uncertain", (
        f"the lag between the covariate and the bias is not determined by this record for {'; '.join(bad)}: the "
        "coefficient and the bias depend on it beyond their stated u; measure the sensor's own temperature, "
        "give the lag (a model file, lag: SECONDS), or use a longer record with faster covariate changes"))]


def _estimate(setup: DriftSetup, m, yy: np.ndarray, method: str, window: int | None):
    """Run model ``m`` of ``setup`` over ``yy`` as the job does: filter, then smooth per ``method``.

    Returns
    -------
    (r, e, bias, bias_var)
        The filter result (its ``loglik``), the estimate used (filtered or
        smoothed; states ``e.x`` and covariances ``e.P``), and the channel
        biases (mc, T) with their variances [unit], [unit^2].
    """
    r = kalman_filter(m, yy)
    e = (rts_smoother(m, r) if method == "smoother" else
         fixed_lag_smoother(m, r, int(window)) if method == "window" else r)
    H = np.broadcast_to(m.H, (yy.shape[1],) + m.H.shape[-2:]) if m.H.ndim == 2 else m.H
    b, bv = channel_bias(setup, H, np.moveaxis(e.x, -1, 0), np.moveaxis(e.P, -1, 0))
    return r, e, b, bv


def _likelihood_weights(ll: np.ndarray) -> np.ndarray:
    """Normalised weights ``exp(ln L_i - max ln L)``, those below :data:`_LAG_NEGLIGIBLE` nats set to 0."""
    w = np.exp(ll - ll.max())
    w[ll < ll.max() - _LAG_NEGLIGIBLE] = 0.0
    return w / w.sum()


#: Lags averaged over: from a third of a sample to a third of the record,
#: log-spaced (a thermal lag is seconds to minutes; below a sample the lag is
#: invisible, above a third of the record it trades with the quantity).
_LAG_POINTS = 25
#: Lags whose likelihood is this many nats below the best carry a relative
#: weight below exp(-12) = 6e-6 and are left out of the average (no smoother
#: pass is spent on them).
_LAG_NEGLIGIBLE = 12.0
#: Level of the test that names a lag piled at the grid's upper edge: lag 0
#: rejected by the likelihood ratio at 95 % (chi-square, 1 dof: 3.84 / 2 nats).
_LAG_DROP = 0.5 * 3.841458820694124


def _lag_average(setup: DriftSetup, dt: np.ndarray, levels: Mapping[str, float], cov: Mapping[str, np.ndarray],
                 x0: np.ndarray, P0: np.ndarray, yy: np.ndarray, method: str, window: int | None,
                 x: np.ndarray, state_var: np.ndarray, bias: np.ndarray, bias_var: np.ndarray,
                 extra_s: np.ndarray | float = 0.0, extra_b: np.ndarray | float = 0.0):
    """Average the states and biases over a covariate lag the record does not fix.

    A covariate-linked bias with no lag given assumes the bias follows the
    recorded covariate at once.  With one sensor the likelihood over a
    first-order lag is nearly flat (1-3 nats over 0-200 s on 600 samples), so
    neither a fitted lag nor lag 0 is a reliable answer.  Instead, with the
    other levels held, the states are recomputed at :data:`_LAG_POINTS` lags
    log-spaced from a third of a sample to a third of the record (a flat
    prior on ln lag over the range the record can show) and averaged with
    the lag's likelihood as weight, ``w_i ~ exp(ln L_i - max ln L)``: the
    mixture's mean and, by the law of total variance, its variance
    ``sum w_i (P_i + (x_i - x_bar)^2)`` (plus the levels' own share, passed
    in ``extra_s``/``extra_b``, computed at lag 0).  The lag's uncertainty is
    then in u, not in a warning.

    The average is still unsupported when the likelihood piles at the
    grid's upper edge (its maximum at a third of the record, and lag 0
    rejected at 95 %, Wilks): a longer lag would be preferred but the
    record cannot hold it, and ``covariate-lag-uncertain`` is named.

    Returns
    -------
    (x, state_var, bias, bias_var, warnings)
        The averaged state means (n, T), their variances (n, T), the
        channel biases (mc, T) and their variances (mc, T), each including
        the extra shares; and ``covariate-lag-uncertain`` or nothing.  With
        no lag to average the inputs are returned with the extras added.
    """
    plain = (x, state_var + extra_s, bias, bias_var + extra_b, [])
    todo = [b for b in setup.biases if b.covariate is not None and not b.fit_lag and b.lag is None]
    if not todo:
        return plain
    span = float(np.sum(dt[1:]))
    step = float(np.median(dt))
    if not span > 3.0 * step:
        return plain
    grid = np.geomspace(step / 3.0, span / 3.0, _LAG_POINTS)

    def lagged(L: float) -> DriftSetup:
        return dataclasses.replace(setup, biases=tuple(dataclasses.replace(b, lag=float(L)) if b in todo else b
                                                       for b in setup.biases))

    try:
        # Likelihoods first (one filter pass per lag, only the number kept: a long
        # record's filter output is large); the states again only where the
        # weight is not negligible, accumulated (no per-lag copy kept).
        ll = np.array([float(kalman_filter(augmented_model(s_, dt, levels, cov, x0=x0, P0=P0), yy).loglik)
                       for s_ in [setup] + [lagged(L) for L in grid]])
        if not np.all(np.isfinite(ll)):
            return plain
        lg = ll[1:]
        w = _likelihood_weights(lg)
        sx = np.zeros(x.shape)
        sxx = np.zeros(x.shape)
        sb = np.zeros(bias.shape)
        sbb = np.zeros(bias.shape)
        for L, wi in zip(grid, w):
            if wi == 0.0:
                continue
            _, e, b_l, bv_l = _estimate(lagged(L), augmented_model(lagged(L), dt, levels, cov, x0=x0, P0=P0), yy,
                                        method, window)
            xs = np.asarray(e.x)
            sx += wi * xs
            sxx += wi * (xs**2 + np.asarray(e.std)**2)
            sb += wi * b_l
            sbb += wi * (b_l**2 + bv_l)
    except Exception:  # a lag the model refuses: nothing to average
        return plain
    x_m, b_m = sx, sb
    # Law of total variance: E[P] + Var[x_hat] = E[P + x_hat^2] - x_bar^2.
    s_var = np.maximum(sxx - sx**2, 0.0) + extra_s
    b_var = np.maximum(sbb - sb**2, 0.0) + extra_b
    warn = []
    if lg.max() - ll[0] > _LAG_DROP:
        names = ", ".join(b.name for b in todo)
        i = int(np.argmax(lg))
        where = (f"rises to the longest lag tried, {grid[-1]:.3g} s, a third of the record" if i == len(grid) - 1
                 else f"peaks at {grid[i]:.3g} s")
        warn.append(named("covariate-lag-uncertain", (
            f"the bias lags the covariate ({names}: the likelihood {where} and rejects lag 0 at 95 %, ratio "
            f"{2 * (lg.max() - ll[0]):.1f}); the coefficient and bias are averaged over the lags the record holds "
            "but with the noise levels of the lag-free model, which the data reject, so they may be off beyond "
            "their stated u; give the lag if it is known (a model file, lag: SECONDS), measure the sensor's own "
            "temperature, or use a longer record with faster covariate changes")))
    return x_m, s_var, b_m, b_var, warn


#: Time constants of a Gauss-Markov quantity averaged over, per decade: the
#: profile likelihood over ln tau is broad (on the wrong-tau records its
#: weights spread over one to two decades), so three points a decade (a
#: factor 2.15) resolve it; the grid holds the tau asked for.
_TAU_PER_DECADE = 3
#: Range of the time constants: from one sample (shorter, the quantity is
#: white noise, traded with the sensor's) to ten record lengths (longer, it
#: is a random walk over the record: the states differ from the random
#: walk's by about span / tau).
_TAU_LOW_SAMPLES = 1.0
_TAU_HIGH_SPANS = 10.0


def _tau_average(setup: DriftSetup, yy: np.ndarray, dt: np.ndarray, cov: Mapping[str, np.ndarray], x0: np.ndarray,
                 P0: np.ndarray, free: Mapping[str, float], given: Mapping[str, float], method: str,
                 window: int | None, rerun: Callable[[DriftSetup, Mapping[str, float]], DriftResult],
                 progress: Callable[[], None] | None) -> DriftResult:
    """The result averaged over the time constant of a Gauss-Markov quantity.

    A Gauss-Markov quantity's ``tau`` is seldom known; a wrong one biases
    the bias estimates beyond their u (a tau 10x too short: band 62-67 %),
    and neither the tau asked for nor the best one on a coarse comparison is
    a reliable answer, as the profile likelihood over ln tau spans one to
    two decades on 600 samples.  As for a covariate lag
    (:func:`_lag_average`), the result is averaged over ``tau`` with a flat
    prior on ln tau, from one sample to ten record lengths, on a grid of
    :data:`_TAU_PER_DECADE` points a decade through the tau asked for:

    1. At each grid point the levels are fitted again (the profile
       likelihood ``ln L_i``; a tau changes the quantity's std that fits),
       walking out from the tau asked for (warm starts) and stopping on a
       side once the likelihood is :data:`_LAG_NEGLIGIBLE` nats below the
       best and falling.
    2. The job runs in full at the most likely grid point ``tau*``
       (comparison, a model swap where its innovations reject it, the
       levels' own u, the covariate-lag average): mean ``x*`` and variance
       ``V*``.
    3. The between-tau part is added by the law of total variance, from
       the states of the model asked for at each grid point's levels
       (weights ``w_i ~ exp(ln L_i - max ln L)``): mean
       ``x* + sum w_i x_i - x_tau*``, variance
       ``V* + sum w_i (P_i + x_i^2) - (sum w_i x_i)^2 - P_tau*``.  The parts
       of ``V*`` beyond ``P_tau*`` (levels' u, lag spread) are taken at
       ``tau*``, as the lag average takes the levels' share at lag 0; a
       nested extension used at ``tau*`` (coloured noise, a fitted lag)
       gets the shift of the states it shares.

    Step 3 is skipped (``applied`` False) when the model used at ``tau*``
    is not a Gauss-Markov quantity of that tau (a random walk taken instead).

    Returns
    -------
    DriftResult
        With ``tau_average`` filled in.
    """
    tau0 = float(setup.signal.tau)
    span = float(np.sum(dt[1:]))
    step = float(np.median(dt))
    lo, hi = _TAU_LOW_SAMPLES * step, _TAU_HIGH_SPANS * max(span, step)
    ratio = 10.0 ** (1.0 / _TAU_PER_DECADE)

    def at(tau: float) -> DriftSetup:
        return dataclasses.replace(setup, signal=dataclasses.replace(setup.signal, tau=float(tau)))

    fits: dict[int, tuple[float, dict[str, float]]] = {}

    def fit(k: int, start: Mapping[str, float]) -> float:
        noise, ll = _fit_levels(at(tau0 * ratio**k), yy, dt, cov, x0, P0, dict(start), given, progress=progress,
                                curvature=False)
        lv = {p.name: p.value for p in noise}
        fits[k] = (float(ll) if np.isfinite(ll) else -np.inf, lv)
        return fits[k][0]

    fit(0, free)
    # Grid indices inside the range; a tau asked for outside it still anchors the grid, and the walk then
    # starts at the nearest point inside.
    k_lo = int(math.ceil(math.log(lo / tau0) / math.log(ratio) - 1e-9))
    k_hi = int(math.floor(math.log(hi / tau0) / math.log(ratio) + 1e-9))
    walks = (range(max(1, k_lo), k_hi + 1), range(min(-1, k_hi), k_lo - 1, -1))
    for walk in walks:
        last, prev = 0, fits[0][0]
        for k in walk:
            try:
                ll = fit(k, {n_: fits[last][1][n_] for n_ in free})
            except Exception:  # a time constant the model refuses: the walk stops there
                break
            best = max(v[0] for v in fits.values())
            if ll < best - _LAG_NEGLIGIBLE and ll < prev:
                break
            last, prev = k, ll
    ks = sorted(fits)
    taus = np.array([tau0 * ratio**k for k in ks])
    ll = np.array([fits[k][0] for k in ks])
    # The prior is flat on ln tau over the range: an anchor outside it only started the walk.
    ll_in = np.where((taus >= lo * (1 - 1e-9)) & (taus <= hi * (1 + 1e-9)), ll, -np.inf) if len(ks) > 1 else ll
    i_best = int(np.argmax(ll_in))
    w = _likelihood_weights(ll_in)
    k_best = ks[i_best]
    res = rerun(at(taus[i_best]), {n_: fits[k_best][1][n_] for n_ in free})
    info = {"asked": tau0, "most_likely": float(taus[i_best]), "taus": taus.tolist(), "weights": w.tolist(),
            "loglik": ll.tolist(), "applied": False}
    used = res.setup
    n0 = len(setup.state_names)
    # The spread comes from the family averaged over (the model asked for at each tau, its own levels); a
    # nested extension used at tau* (coloured noise, a covariate lag) has the same states first, so the shift
    # applies to them.  Another model (a random walk) is not of the family: nothing is added.
    if not (used is not None and used.signal.kind == "gauss_markov" and used.signal.tau == taus[i_best]
            and tuple(used.state_names[:n0]) == tuple(setup.state_names)
            and tuple(used.biased_channels) == tuple(setup.biased_channels)):
        return dataclasses.replace(res, tau_average=info)
    sx = sxx = sb = sbb = 0.0
    star = None
    try:
        for i, (k, wi) in enumerate(zip(ks, w)):
            if wi == 0.0 and i != i_best:
                continue
            s_ = at(taus[i])
            _, e, b_i, bv_i = _estimate(s_, augmented_model(s_, dt, fits[k][1], cov, x0=x0, P0=P0), yy, method,
                                        window)
            x_i, xv_i = np.asarray(e.x), np.asarray(e.std) ** 2
            if i == i_best:
                star = (b_i, bv_i, x_i, xv_i)
            sx = sx + wi * x_i
            sxx = sxx + wi * (x_i**2 + xv_i)
            sb = sb + wi * b_i
            sbb = sbb + wi * (b_i**2 + bv_i)
    except Exception:  # a grid point the model refuses: the result at tau* stands
        return dataclasses.replace(res, tau_average=info)
    b_s, bv_s, x_s, xv_s = star
    if res.bias.shape != b_s.shape or res.state.shape[1:] != x_s.shape[1:]:
        return dataclasses.replace(res, tau_average=info)
    # Law of total variance over tau, the shares beyond the filter's P kept from tau*.
    bias = res.bias + (sb - b_s)
    b_var = np.maximum(res.bias_std**2 + (sbb - sb**2) - bv_s, 0.0)
    x, x_var = np.array(res.state, dtype=float), np.asarray(res.state_std, dtype=float) ** 2
    x[:n0] += sx - x_s
    x_var[:n0] = np.maximum(x_var[:n0] + (sxx - sx**2) - xv_s, 0.0)
    info["applied"] = True
    return dataclasses.replace(res, bias=bias, bias_std=np.sqrt(b_var), state=x, state_std=np.sqrt(x_var),
                               corrected=res.corrected - (bias - res.bias), tau_average=info)


def _reference_warnings(setup: DriftSetup) -> list[str]:
    """Warn when a defaulted covariate reference fixes a channel's offset.

    Without an additive bias on the same channel, the bias is *defined* as
    zero at the covariate's record mean; a real sensor's offset at that
    temperature is then silently taken as part of the quantity, and no
    stated u includes it.
    """
    out = []
    for b in setup.biases:
        if b.covariate is None or b.reference is not None:
            continue
        if any(o.channel == b.channel and o.covariate is None for o in setup.biases):
            continue
        out.append(named("covariate-reference-defaulted", (
            f"the bias of {b.channel} is taken as zero at the mean of {b.covariate} over this record (no "
            f"reference given), so its offset there is not estimated and not in the stated u; give "
            f"--covariate-reference (the {b.covariate} of the sensor's last calibration)")))
    return out


def channel_residuals(innovation: np.ndarray, innovation_cov: np.ndarray, H_signal: np.ndarray) -> np.ndarray:
    """Standardised innovations with the common (signal) part removed.

    With redundant sensors, a misfit of the signal model (a smooth trend
    that a random walk follows with a lag) shifts every channel's innovation
    alike; a channel's own drift does not.  Removing the generalised
    least-squares fit of the signal directions ``H_s`` leaves the parity
    residual ``r = v - H_s (H_s' S^-1 H_s)^-1 H_s' S^-1 v`` with covariance
    ``S - H_s (H_s' S^-1 H_s)^-1 H_s'``; each component is divided by its
    standard deviation.  Without redundancy (as many channels as signal
    states) the plain standardised innovation is returned.

    Parameters
    ----------
    innovation : ndarray, (m, T)
    innovation_cov : ndarray, (m, m, T)
    H_signal : ndarray, (m, ns)

    Returns
    -------
    ndarray, (m, T)
        N(0, 1) per component under the model; NaN where a measurement is
        missing or the component carries no channel-specific information.

    References
    ----------
    J. E. Potter, M. C. Suman, "Thresholdless redundancy management with
    arrays of skewed instruments", AGARDograph 224 (1977) (parity space).
    """
    v = np.moveaxis(innovation, -1, 0)
    S = np.moveaxis(innovation_cov, -1, 0)
    m, ns = H_signal.shape
    sd = np.sqrt(np.diagonal(S, axis1=1, axis2=2))
    if np.linalg.matrix_rank(H_signal) >= m:
        return (v / sd).T
    ok = ~np.isnan(v).any(axis=1)
    z = np.full(v.shape, np.nan)
    Si = np.linalg.inv(S[ok])
    A = np.einsum("ia,tij,jb->tab", H_signal, Si, H_signal)
    G = np.einsum("ia,tab,jb->tij", H_signal, np.linalg.inv(A), H_signal)
    r = v[ok] - np.einsum("tij,tjk,tk->ti", G, Si, v[ok])
    var = np.diagonal(S[ok] - G, axis1=1, axis2=2)
    scale = np.diagonal(S[ok], axis1=1, axis2=2)
    good = var > 1e-9 * scale
    zz = np.where(good, r / np.sqrt(np.where(good, var, 1.0)), np.nan)
    z[ok] = zz
    return z.T


def _broad_bias_levels(setup: DriftSetup, noise: Sequence[NoiseParameter],
                       scale: Mapping[str, float]) -> dict[str, float]:
    """Estimated bias levels whose likelihood does not exclude zero, with a scale to start from.

    A bias level (random-walk rate, Gauss-Markov std, ramp slope rate) of a
    channel with coloured (AR) noise whose estimate is within two standard
    uncertainties of zero, or at a search bound, or without a finite u:
    there the log-normal approximation of :func:`_level_uncertainty` does
    not describe the likelihood (the coloured noise takes all but the few
    lowest frequencies, through which alone the bias rate is seen; under
    AR(1) noise of rho 0.8 on 600 samples its ML value is zero in about one
    record in eight, and those records' bands missed).  Such levels are
    integrated over instead (:func:`_level_quadrature`).  On white-noise
    channels the normal approximation covers (white 94 %, covariate 97 %,
    known 95 %, 100 seeds), and the flat prior would make a bias that truly
    does not drift over-cover (covariate: 100 %, z spread 0.66), so they
    are left to it.
    """
    out = {}
    coloured = {b.level_name for b in setup.biases if b.channel in setup.ar_noise}
    for p in noise:
        if not p.estimated or p.name not in coloured:
            continue
        if p.at_bound or p.std is None or not np.isfinite(p.std) or p.value <= 2.0 * p.std:
            out[p.name] = max(p.value + (p.std if p.std is not None and np.isfinite(p.std) else 0.0),
                              1e-3 * float(scale.get(p.name, 0.0)), 1e-300)
    return out


#: Log-likelihood drop [nats] at which the quadrature over a bias level stops:
#: the likelihood there is e^-8 = 3e-4 of its peak, below the 1e-3 resolution
#: that a 95 % band's variance needs.
_QUAD_DROP = 8.0
#: Points of the quadrature over one level (uniform grid from 0 to the drop):
#: the 8-nat width spans at least eight of them.
_QUAD_POINTS = 17


def _level_uncertainty(setup: DriftSetup, build, yy: np.ndarray, levels: Mapping[str, float], lcov: Mapping,
                       method: str, window: int | None, x: np.ndarray, P: np.ndarray,
                       bias: np.ndarray, bias_var: np.ndarray, quad: Mapping[str, float] | None = None,
                       loglik: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What the noise levels' own uncertainty adds to the variance of the biases and states.

    The filter's covariance is that of the states *given* the levels; the
    levels are estimates.  Over ``ln(levels) ~ N(theta, C)`` the total
    variance is ``E[P] + Var[x_hat]`` (Hamilton 1986); both come from
    central differences along the principal axes ``L_i`` of ``C`` (2p more
    passes): ``E[P] ~ P + sum_i ((P+ + P-) / 2 - P)`` and ``Var[x_hat] ~
    sum_i ((x+ - x-) / 2)^2``, exact for a quadratic dependence.  Levels at
    a search bound (no finite u) are held.  Matters where a level is poorly
    determined: a bias random walk under coloured noise is estimated to a
    factor of two on 600 samples, and the plug-in band covered 87 % instead
    of 95 % (95.0 % with the true levels).

    Bias levels in ``quad`` (whose likelihood does not exclude zero, see
    :func:`_broad_bias_levels`) are integrated over instead, one at a time
    with the others held (:func:`_level_quadrature`), and left out of the
    normal approximation (their marginal is dropped from ``C``).

    Returns
    -------
    extra_bias : ndarray, (mc, T)
    extra_state : ndarray, (n, T)
        Added variances (>= 0) [unit^2], [state unit^2].

    References
    ----------
    J. D. Hamilton, "A standard error for the estimated state vector of a
    state-space model", J. Econometrics 33 (1986) 387-397.
    """
    quad = dict(quad or {})
    zero_b, zero_s = np.zeros_like(bias_var), np.zeros(x.shape)
    Ps = np.diagonal(P, axis1=0, axis2=1).T  # (n, T)
    q_b, q_s = zero_b.copy(), zero_s.copy()
    for k, s0 in quad.items():
        qb, qs = _level_quadrature(setup, build, yy, levels, k, s0, method, window, x, Ps, bias, bias_var,
                                   loglik)
        q_b += qb
        q_s += qs
    names = [k for k in lcov.get("names", ())]
    C = np.asarray(lcov.get("cov", np.zeros((0, 0))), dtype=float)
    if quad and names:
        kept = [i for i, k in enumerate(names) if k not in quad]
        C = C[np.ix_(kept, kept)]
        names = [names[i] for i in kept]
    # Levels with a finite u on a log scale below one (known to better than a
    # factor e): a worse-determined level is one that collapsed towards zero
    # (its size, not its effect, is uncertain), and a step of its log-sd would
    # leave the region where the quadratic approximation means anything.
    d = np.diag(C) if names else np.zeros(0)
    ok = [i for i in range(len(names)) if np.isfinite(d[i]) and 0.0 < d[i] <= 1.0]
    if not ok:
        return q_b, q_s
    C = np.nan_to_num(C[np.ix_(ok, ok)], nan=0.0, posinf=0.0, neginf=0.0)
    names = [names[i] for i in ok]
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    keep = w > 1e-12 * max(w.max(), 1e-300)
    axes = (V[:, keep] * np.sqrt(w[keep])).T
    e_b, e_s = zero_b.copy(), zero_s.copy()
    v_b, v_s = zero_b.copy(), zero_s.copy()
    for a in axes:
        out = []
        for sgn in (1.0, -1.0):
            lv = dict(levels)
            for k, d in zip(names, a):
                lv[k] = float(levels[k] * np.exp(sgn * d))
            try:
                _, e, b, bv = _estimate(setup, build(lv), yy, method, window)
            except Exception:  # a level set the model refuses: this axis adds nothing
                out = []
                break
            out.append((b, bv, e.x, np.diagonal(e.P, axis1=0, axis2=1).T))
        if len(out) != 2:
            continue
        (bp, bvp, xp_, sp), (bm, bvm, xm, sm) = out
        e_b += 0.5 * (bvp + bvm) - bias_var
        e_s += 0.5 * (sp + sm) - Ps
        v_b += (0.5 * (bp - bm)) ** 2
        v_s += (0.5 * (xp_ - xm)) ** 2
    return np.maximum(e_b + v_b, 0.0) + q_b, np.maximum(e_s + v_s, 0.0) + q_s


def _level_quadrature(setup: DriftSetup, build, yy: np.ndarray, levels: Mapping[str, float], name: str,
                      scale: float, method: str, window: int | None, x: np.ndarray,
                      Ps: np.ndarray, bias: np.ndarray, bias_var: np.ndarray,
                      loglik: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Variance added by a bias level the record does not bound away from zero.

    The level ``s`` (others held at their estimates) is integrated over its
    likelihood with a flat prior on ``s`` itself (a standard deviation or a
    rate; Gelman 2006), on a uniform grid from 0 to where the log-likelihood
    has dropped by :data:`_QUAD_DROP` nats (found by doubling from
    ``scale``).  With weights ``w_j`` proportional to ``L(s_j)``, the
    estimate stays the ML one and its variance becomes
    ``sum_j w_j (P_j + (x_j - x_hat)^2)``, the mean squared error over the
    levels the data allow; what is returned is that minus the ML ``P``.

    Returns
    -------
    extra_bias : ndarray, (mc, T)
    extra_state : ndarray, (n, T)
        Added variances (>= 0) [unit^2], [state unit^2].

    References
    ----------
    A. Gelman, "Prior distributions for variance parameters in hierarchical
    models", Bayesian Analysis 1 (2006) 515-534 (a flat prior on the
    standard deviation); J. D. Hamilton (1986), as :func:`_level_uncertainty`.
    """
    zero = (np.zeros_like(bias_var), np.zeros(x.shape))

    def ll_at(v: float) -> float:
        return float(kalman_filter(build({**levels, name: v}), yy).loglik)

    try:
        ll0 = ll_at(levels[name]) if loglik is None else float(loglik)
        hi = float(scale)
        for _ in range(60):
            if ll_at(hi) < ll0 - _QUAD_DROP:
                break
            hi *= 2.0
        else:
            return zero
        out = []
        for v in np.linspace(0.0, hi, _QUAD_POINTS):
            r, e, b, bv = _estimate(setup, build({**levels, name: float(v)}), yy, method, window)
            out.append((float(r.loglik), b, bv, e.x, np.diagonal(e.P, axis1=0, axis2=1).T))
    except Exception:  # a level the model refuses: the quadrature adds nothing
        return zero
    ll = np.array([o[0] for o in out])
    if not np.all(np.isfinite(ll)):
        return zero
    w = np.exp(ll - ll.max())
    w /= w.sum()
    eb = sum(wj * (o[2] + (o[1] - bias) ** 2) for wj, o in zip(w, out)) - bias_var
    es = sum(wj * (o[4] + (o[3] - x) ** 2) for wj, o in zip(w, out)) - Ps
    return np.maximum(eb, 0.0), np.maximum(es, 0.0)


def _blocks(setup: DriftSetup) -> list[tuple[str, ...]]:
    """Groups of channels whose likelihoods are independent.

    With a known quantity (its state held at the given value) nothing links
    the channels: each has its own biases and noise, so the likelihood is a
    sum over channels and each channel's levels are estimated on their own
    (a two-level search per channel instead of one over all of them).
    Otherwise the quantity couples every channel.
    """
    if setup.signal.kind == "known" and len(setup.channels) > 1:
        return [(c,) for c in setup.channels]
    return [tuple(setup.channels)]


def _sub_setup(setup: DriftSetup, chans: Sequence[str]) -> DriftSetup:
    """The set-up restricted to some channels (their biases and coloured noise)."""
    return DriftSetup(channels=tuple(chans), signal=setup.signal,
                      biases=tuple(b for b in setup.biases if b.channel in chans),
                      noise_std={c: v for c, v in setup.noise_std.items() if c in chans},
                      trusted=tuple(c for c in setup.trusted if c in chans),
                      ar_noise=tuple(c for c in setup.ar_noise if c in chans))


def _fit_workers() -> int:
    """Threads for independent blocks: the CPUs this process may use, at most 4 (``SENSCAL_THREADS`` overrides)."""
    env = os.environ.get("SENSCAL_THREADS", "")
    if env.strip().isdigit():
        return max(1, int(env))
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(4, n))


def _fit_levels(setup: DriftSetup, yy: np.ndarray, dt: np.ndarray, cov: Mapping[str, np.ndarray],
                x0: np.ndarray, P0: np.ndarray, free: Mapping[str, float], given: Mapping[str, float],
                starts: Sequence[Mapping[str, float]] = (),
                progress: Callable[[], None] | None = None,
                cov_out: dict | None = None, curvature: bool = True) -> tuple[list[NoiseParameter], float]:
    """Maximum-likelihood levels, block by independent block, with the analytic score.

    ``curvature`` False skips the levels' uncertainties (a compared model needs only its likelihood).

    Returns the levels in ``setup.level_names()`` order (given ones
    included) and the maximised log-likelihood (the sum over blocks);
    ``cov_out`` receives the covariance of the free levels' logs
    (block-diagonal across blocks), as :func:`estimate_levels` gives it.
    """
    dtu = _uniform_dt(dt)
    out: dict[str, NoiseParameter] = {}

    def fit_block(chans):
        sub = setup if len(chans) == len(setup.channels) else _sub_setup(setup, chans)
        idx = [setup.state_names.index(nm) for nm in sub.state_names]
        rows = [setup.channels.index(c) for c in chans]
        names = set(sub.level_names())
        f = {k: v for k, v in free.items() if k in names}
        g = {k: v for k, v in given.items() if k in names}
        score = LevelLikelihood(sub, dtu, yy[rows], {c: cov[c] for c in sub.covariates}, x0[idx],
                                P0[np.ix_(idx, idx)], list(f))
        co: dict = {}
        # A covariate lag longer than a third of the record would freeze the
        # covariate over it (its coefficient then trades with the quantity).
        span = float(np.sum(dt[1:])) if dt.size > 1 else 1.0
        step = float(np.median(dt))
        bounds = {k: (0.01 * step, max(span / 3.0, 0.02 * step)) for k in f if k.endswith("_lag")}
        with one_blas_thread():
            params, ll = estimate_levels(None, yy[rows], f, g, starts=[{k: s_[k] for k in f} for s_ in starts],
                                         progress=progress, score=score, cov_out=co, bounds=bounds,
                                         curvature=curvature)
        return co, params, ll

    blocks = _blocks(setup)
    workers = min(len(blocks), _fit_workers())
    if workers > 1:
        # Independent blocks (a known quantity's channels) in threads: the
        # score pass releases the GIL, so two cores take two channels at once.
        with ThreadPoolExecutor(workers) as ex:
            fits = list(ex.map(fit_block, blocks))
    else:
        fits = [fit_block(c) for c in blocks]
    covs = [co for co, _, _ in fits]
    total = 0.0
    for _, params, ll in fits:
        out.update({p.name: p for p in params})
        total += ll
    order = [k for k in given] + [k for k in setup.level_names() if k not in given]
    if cov_out is not None:
        names = [k for co in covs for k in co["names"]]
        # Independent blocks: zero covariance between them.
        C = np.zeros((len(names), len(names)))
        i = 0
        for co in covs:
            k = len(co["names"])
            C[i:i + k, i:i + k] = co["cov"]
            i += k
        cov_out["names"], cov_out["cov"] = names, C
    return [out[k] for k in order], total


def _detect(build, setup: DriftSetup, levels: Mapping[str, float], yy: np.ndarray, rows: list[int], dt: float,
            false_alarm_rate: float, detect_shift: float):
    """CUSUM drift onsets on the no-drift model's channel residuals.

    Under the no-drift hypothesis every bias is constant (zero process
    noise).  The residuals are the standardised innovations with the common
    signal part removed (:func:`channel_residuals`).  A drifting channel
    still leaks into the others' residuals; once a channel alarms, its
    biases are freed (their estimated levels) and the remaining channels are
    tested again, until no new channel alarms (isolation of the faulty
    sensor).
    """
    arl0 = 3600.0 / (false_alarm_rate * dt)
    chans = [setup.channels[r] for r in rows]
    onset = {c: -1 for c in chans}
    alarm = {c: -1 for c in chans}
    free: set[str] = set()
    ns = setup.signal.n_states
    det = None
    for _ in range(len(rows)):
        lv = dict(levels)
        lv.update({b.level_name: 0.0 for b in setup.biases if b.channel not in free})
        # A ramp bias with no slope noise is still a straight line of unknown
        # slope; "no drift" holds its slope at zero.
        frozen = [i for i, (c, nm) in enumerate(zip(setup.state_channels, setup.state_names))
                  if c is not None and c not in free and nm.endswith("_slope")]
        model = build(lv, frozen)
        nres = kalman_filter(model, yy)
        if setup.signal.kind == "known":
            # Nothing common to remove: the quantity is given.
            sd = np.sqrt(np.diagonal(nres.innovation_cov, axis1=0, axis2=1)).T
            z = nres.innovation / sd
        else:
            Hs = (model.H if model.H.ndim == 2 else model.H[0])[:, :ns]
            z = channel_residuals(nres.innovation, nres.innovation_cov, Hs)
        test = [i for i, c in enumerate(chans) if c not in free]
        det = cusum(z[[rows[i] for i in test]], arl0, k=0.5 * detect_shift)
        hit = [(det.alarm[j], test[j], det.onset[j]) for j in range(len(test)) if det.alarm[j] >= 0]
        if not hit:
            break
        a, i, o = min(hit)
        alarm[chans[i]] = int(a)
        onset[chans[i]] = int(o)
        free.add(chans[i])
    return det, onset, alarm


def channel_bias(setup: DriftSetup, H: np.ndarray, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total bias of each corrected channel and its variance, from augmented-state estimates.

    The bias of a channel is ``E_t x_t`` with ``E_t`` the bias columns of
    its row of ``H_t`` (a covariate-linked term weighted by the referenced
    covariate), its variance ``E_t P_t E_t'``.

    Parameters
    ----------
    setup : DriftSetup
    H : ndarray, (T, m, n)
        Measurement matrices.
    x : ndarray, (T, n)
        State estimates (time first).
    P : ndarray, (T, n, n)
        Their covariances.

    Returns
    -------
    bias, variance : ndarray, (mc, T)
        Rows: ``setup.biased_channels`` [unit] and [unit^2].
    """
    rows = [setup.channels.index(c) for c in setup.biased_channels]
    E = np.array(H[:, rows, :], copy=True)
    E[:, :, :setup.signal.n_states] = 0.0
    # Coloured-noise states are noise, not bias: the corrected output keeps them.
    E[:, :, setup.signal.n_states + setup.n_bias_states:] = 0.0
    return np.einsum("tcn,tn->ct", E, x), np.einsum("tcn,tnk,tck->ct", E, P, E)


def drift_prior(setup: DriftSetup, y: np.ndarray, covariates: Mapping[str, np.ndarray],
                duration: float, *, spread: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Prior mean and covariance of the augmented state from the data.

    The quantity near the first samples, biases near zero, both ten times
    wider than the data's spread so the data dominate, yet not so vague that
    the first updates lose precision to cancellation.

    Parameters
    ----------
    setup : DriftSetup
    y : ndarray, (m, T)
        Measurements [unit], already minus the known mean of a
        ``gauss_markov`` / ``known`` quantity.
    covariates : mapping of str to ndarray (T,)
        Referenced covariates (``c - c_ref``) [covariate unit].
    duration : float
        Record length [s] (scales a ramp's slope prior).
    spread : float, optional
        Typical size of the quantity and biases [unit] that sets the prior
        widths; default the data's spread (a fleet gives one per channel
        group, so that its channels share their covariance).

    Returns
    -------
    x0 : ndarray, (n,)
    P0 : ndarray, (n, n)
        Diagonal [state units^2].
    """
    yy = np.asarray(y, dtype=float)
    n = len(setup.state_names)
    ns = setup.signal.n_states
    T = yy.shape[-1]
    if spread is None:
        spread = max(float(np.nanstd(yy)), float(np.nanmax(np.abs(yy))) * 1e-6, 1e-300)
    duration = duration if duration > 0 else 1.0
    x0 = np.zeros(n)
    p0 = np.full(n, (10.0 * spread) ** 2)
    if setup.signal.kind == "known":
        p0[:ns] = 0.0
    elif setup.signal.kind != "matrix":
        first = yy[:, : min(T, 10)]
        x0[0] = float(np.nanmedian(first)) if np.isfinite(first).any() else 0.0
    else:
        p0[:ns] = (1e3 * max(spread, float(np.nanmax(np.abs(yy))))) ** 2
    j = ns
    for b in setup.biases:
        scale = 1.0
        if b.covariate is not None:
            scale = 1.0 / max(float(np.std(covariates[b.covariate])), 1e-300)
        p0[j] = (10.0 * spread * scale) ** 2
        if b.dynamics == "ramp":
            # A slope that moves the bias by ten spreads over the record.
            p0[j + 1] = (10.0 * spread * scale / duration) ** 2
        j += len(b.state_names)
    return x0, np.diag(p0)


def correct_drift(setup: DriftSetup, y: Any, t: Any, covariates: Mapping[str, Any] | None = None, *,
                  window: int | None = None, smooth: bool = False,
                  false_alarm_rate: float = DEFAULT_FALSE_ALARM_RATE, detect_shift: float = 1.0,
                  estimate: bool = True, compare: bool = True, start: Mapping[str, float] | None = None,
                  progress: Callable[[], None] | None = None, select: bool = True,
                  level_u: bool = True, _fit_only: bool = False, _lag_check: bool = False) -> DriftResult:
    """Estimate and remove slowly drifting biases.

    The augmented state ``[signal; biases]`` (patent step a) is filtered
    (step c), optionally with a fixed-lag window of ``window`` samples
    (step b) or the full RTS smoother; the corrected measurement is
    ``y - b_hat``.  Noise levels not fixed in ``setup`` are estimated by
    maximum likelihood first.  Drift onsets are detected by a CUSUM on the
    standardised innovations of the no-drift model (biases held constant).

    Parameters
    ----------
    setup : DriftSetup
        What drifts (see :func:`redundant_setup`, :func:`covariate_setup`,
        :func:`load_model_yaml`).
    y : array_like, (m, T)
        Measurements of ``setup.channels`` [unit]; NaN = missing.
    t : array_like, (T,)
        Time [s], strictly increasing.
    covariates : mapping of str to array_like (T,), optional
        Covariate channels named by the set-up's biases [covariate unit].
    window : int, optional
        Fixed-lag window in samples (latency traded for accuracy).
    smooth : bool
        Offline: use all data (RTS smoother).  Excludes ``window``.
    false_alarm_rate : float
        Drift detector false alarms per hour per channel.
    detect_shift : float
        Mean shift of the standardised innovations the detector is tuned to
        (CUSUM reference ``k = detect_shift / 2``) [standard deviations].
    estimate : bool
        Estimate the noise levels not given; if False they must all be given.
    compare : bool
        Also fit the alternative models (a Gauss-Markov quantity against a
        random walk and against tau x 0.1 and x 10; random-walk <-> ramp
        biases; coloured AR(1) measurement noise; a first-order lag on each
        covariate) and compare AIC.  Costs one more estimation per
        alternative.
    select : bool
        With ``compare``: use a nested extension (coloured noise, covariate
        lag) when AIC prefers it, and another model when the one asked for
        fails its innovation tests and an alternative has the lower AIC
        (``selected`` names it); otherwise, and with ``select`` False, a
        lower AIC only raises ``better-model``.
    level_u : bool
        Include the estimated noise levels' own uncertainty in ``bias_std``
        and ``state_std`` (Hamilton 1986; 2 more passes per estimated
        level).  False gives the filter's covariance at the estimated
        levels, as a ``--state`` tracker that keeps them does.
    start : mapping of str to float, optional
        Starting values of the maximum-likelihood search for some levels
        (e.g. from Allan deviations, :func:`senscal.drift.allan.drift_levels_from_allan`);
        the others start from the differenced moments.
    progress : callable, optional
        Called once per likelihood evaluation (progress display).

    Returns
    -------
    DriftResult

    Raises
    ------
    UnobservableError
        When the biases cannot be told from the signal.
    InputError, DataError
        Bad shapes, missing covariates, too few samples.

    References
    ----------
    Patent CN102564486A, Shanghai Dianji University (2012): correction of
    slow-drift faults by an augmented Kalman filter (steps a-c, claim 4).
    """
    # Only small matrices here: a threaded BLAS only adds wake-up latency
    # (see senscal.drift._blas).
    with one_blas_thread():
        return _correct_drift(setup, y, t, covariates, window=window, smooth=smooth,
                              false_alarm_rate=false_alarm_rate, detect_shift=detect_shift, estimate=estimate,
                              compare=compare, start=start, progress=progress, select=select,
                              level_u=level_u, _fit_only=_fit_only, _lag_check=_lag_check)


def _correct_drift(setup, y, t, covariates, *, window, smooth, false_alarm_rate, detect_shift, estimate, compare,
                   start, progress, select, level_u, _fit_only, _lag_check=False, _tau_fixed=False):
    yy = np.array(y, dtype=float)
    if yy.ndim == 1:
        yy = yy[None]
    m = len(setup.channels)
    if yy.ndim != 2 or yy.shape[0] != m:
        raise InputError(f"y must have shape ({m}, T) for channels {', '.join(setup.channels)}, got {np.shape(y)}")
    tt = np.asarray(t, dtype=float).reshape(-1)
    T = yy.shape[1]
    if tt.size != T:
        raise InputError(f"t has {tt.size} samples but y has {T}")
    if T < 10:
        raise TooFewSamplesError(f"drift correction needs at least 10 samples, got {T}")
    if not np.all(np.isfinite(tt)) or np.any(np.diff(tt) <= 0):
        raise DataError("time stamps must be finite and strictly increasing")
    if np.any(np.isinf(yy)):
        raise DataError("measurements contain inf; use NaN for a missing sample")
    for i, c in enumerate(setup.channels):
        if np.isnan(yy[i]).all():
            raise DataError(f"channel {c} has no valid sample")
    if window is not None and smooth:
        raise InputError("choose either a window (fixed-lag smoother) or the full smoother, not both")
    if window is not None and (int(window) != window or window < 1):
        raise InputError(f"the window must be a whole number of samples >= 1, got {window}")
    if not false_alarm_rate > 0:
        raise InputError(f"the false-alarm rate must be > 0 per hour, got {false_alarm_rate}")
    cov: dict[str, np.ndarray] = {}
    covariates = covariates or {}
    for name in setup.covariates:
        if name not in covariates:
            raise InputError(f"covariate {name} is needed by the set-up but was not given")
        c = np.asarray(covariates[name], dtype=float).reshape(-1)
        if c.size != T or not np.all(np.isfinite(c)):
            raise DataError(f"covariate {name} must have {T} finite samples (interpolate gaps first)")
        refs = {b.reference for b in setup.biases if b.covariate == name} - {None}
        if len(refs) > 1:
            raise InputError(f"covariate {name} is given different reference values {sorted(refs)}; use one")
        ref = refs.pop() if refs else float(np.mean(c))
        cov[name] = c - ref
        if not (math.isfinite(ref) and np.all(np.abs(cov[name]) < 1e154)):
            # The filter squares the referenced covariate (1e308 made the eigenvalue solver fail).
            raise InputError(f"covariate {name} minus its reference {ref:g} reaches "
                             f"{float(np.max(np.abs(cov[name]))):.3g}; give a reference within the covariate's "
                             "range (--covariate-reference, e.g. the value at the last calibration)")
    dt = np.empty(T)
    dt[1:] = np.diff(tt)
    dt[0] = dt[1]
    y_raw = yy
    if setup.signal.kind in ("gauss_markov", "known"):
        # Known mean: the filter works on the deviation.
        yy = yy - setup.signal.mean

    # Independent blocks are observable one by one (a 100-channel known
    # quantity: 100 one-state checks instead of one of 101 states).
    for chans in _blocks(setup):
        sub = setup if len(chans) == len(setup.channels) else _sub_setup(setup, chans)
        check_observable(sub, dt, {c: cov[c] for c in sub.covariates})

    names = setup.state_names
    n = len(names)
    ns = setup.signal.n_states
    duration = float(tt[-1] - tt[0])
    x0, P0 = drift_prior(setup, yy, cov, duration)

    def build(levels: Mapping[str, float], frozen: Sequence[int] = ()):
        P = P0
        if len(frozen):
            P = P0.copy()
            P[list(frozen), list(frozen)] = 0.0
        return augmented_model(setup, dt, levels, cov, x0=x0, P0=P)

    given = setup.given_levels()
    missing = [k for k in setup.level_names() if k not in given]
    if missing and not estimate:
        raise InputError(f"noise levels {', '.join(missing)} are not given; give them or allow estimation")
    mom = moment_levels(yy)
    step = float(np.median(dt))
    first_start = _moment_levels_start(setup, yy, step, duration, cov, mom)
    for k, v in (start or {}).items():
        if k in first_start and math.isfinite(v) and v > 0:
            first_start[k] = float(v)
    other = _starting_levels(setup, yy, step, duration, cov)
    if (compare and estimate and select and not _fit_only and not _lag_check and not _tau_fixed
            and setup.signal.kind == "gauss_markov" and not setup.signal.tau_known
            and "signal_std" in missing):
        # The time constant is a starting point, not a fact: average over the ones the record allows.
        def rerun(s_: DriftSetup, start_: Mapping[str, float]) -> DriftResult:
            return _correct_drift(s_, y, t, covariates, window=window, smooth=smooth,
                                  false_alarm_rate=false_alarm_rate, detect_shift=detect_shift, estimate=estimate,
                                  compare=compare, start=start_, progress=progress, select=select,
                                  level_u=level_u, _fit_only=False, _lag_check=False, _tau_fixed=True)

        return _tau_average(setup, yy, dt, cov, x0, P0, {k: first_start[k] for k in missing}, given,
                            "smoother" if smooth else "window" if window is not None else "filter", window, rerun,
                            progress)
    lcov: dict = {}
    noise, loglik = _fit_levels(setup, yy, dt, cov, x0, P0, {k: first_start[k] for k in missing}, given,
                                progress=progress, cov_out=lcov, curvature=not _fit_only)
    if missing and _degenerate(setup, noise, mom):
        # A collapsed solution: search again from the spread-based start too
        # and keep the most likely (a second start costs a full search, so it
        # is spent only when the first one is suspect).
        noise, loglik = _fit_levels(setup, yy, dt, cov, x0, P0, {k: first_start[k] for k in missing}, given,
                                    starts=[{k: other[k] for k in missing}], progress=progress, cov_out=lcov,
                                    curvature=not _fit_only)
    if _fit_only:
        # Model comparison needs only the maximised likelihood.
        return noise, loglik
    levels = {p.name: p.value for p in noise}
    warnings: list[str] = []
    warnings += _degenerate(setup, noise, mom)
    warnings += _lag_warnings(noise)
    model = build(levels)
    res = kalman_filter(model, yy)
    if smooth:
        est = rts_smoother(model, res)
        method = "smoother"
    elif window is not None:
        est = fixed_lag_smoother(model, res, int(window))
        method = "window"
    else:
        est = res
        method = "filter"
    x, P = est.x, est.P
    state_std = est.std

    Hb = np.broadcast_to(model.H, (T,) + model.H.shape[-2:]) if model.H.ndim == 2 else model.H
    chans = setup.biased_channels
    rows = [setup.channels.index(c) for c in chans]
    bias, bias_var = channel_bias(setup, Hb, np.moveaxis(x, -1, 0), np.moveaxis(P, -1, 0))
    shift = setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else 0.0
    y_c = yy[rows] + shift
    corrected = y_c - bias

    # Model adequacy: the prior's transient (a few times the number of
    # states) is left out of the innovation tests.
    check = innovation_checks(res.normalized_innovation, skip=min(T // 10, 5 * n))
    if not check.adequate:
        warnings.append(named("model-inadequate", (
            f"the filter's innovations are not white noise of unit scale (whiteness p = {check.whiteness_p:.1g}, "
            f"mean normalised innovation squared {check.nis:.3g}, p = {check.nis_p:.1g}), so the stated bias "
            "uncertainties assume a model the data reject; try another --signal / --signal-tau or "
            "--bias-dynamics ramp, or give a model file")))
    comparison: tuple = ()
    if compare and estimate:
        comparison, alt_setups = _compare_models(setup, y_raw, tt, covariates, float(res.loglik), len(missing))
        asked = comparison[0]["aic"]
        better = [c for c in comparison[1:] if c["aic"] < asked - _AIC_MARGIN]
        # A nested extension (coloured noise, a covariate lag) may be taken
        # whenever AIC prefers it; a different model only when the one asked
        # for is rejected by its own innovations too.  Of those, the lowest AIC.
        eligible = [c for c in better if c["nested"] or not check.adequate]
        pick = min(eligible, key=lambda c: c["aic"]) if eligible else None
        if pick is not None and select:
            res2 = correct_drift(alt_setups[pick["model"]], y_raw, tt, covariates, window=window, smooth=smooth,
                                 false_alarm_rate=false_alarm_rate, detect_shift=detect_shift, compare=False,
                                 start=start, progress=progress, level_u=level_u,
                                 # The model used is checked for a covariate lag as the one asked for would be.
                                 _lag_check=True)
            w2 = list(res2.warnings) + _colour_warning(comparison[0], pick)
            rest = [c for c in better if c is not pick and c["aic"] < pick["aic"] - _NAME_MARGIN]
            if rest:
                b = min(rest, key=lambda c: c["aic"])
                w2.append(named("better-model", (
                    f"the data favour {b['model']} over the model used ({pick['model']}, chosen by AIC; AIC lower "
                    f"by {pick['aic'] - b['aic']:.1f}); rerun with it")))
            return dataclasses.replace(res2, comparison=comparison, selected=pick["model"], warnings=tuple(w2))
        named_ = [c for c in better if c["aic"] < asked - _NAME_MARGIN]
        if named_:
            b = min(named_, key=lambda c: c["aic"])
            warnings.append(named("better-model", (
                f"the data favour {b['model']} over the model used (AIC lower by "
                f"{asked - b['aic']:.1f}); rerun with it")))
    warnings += _reference_warnings(setup)
    extra_b, extra_s = 0.0, 0.0
    if level_u:
        # After the comparison: a model replaced by an alternative needs no band.
        extra_b, extra_s = _level_uncertainty(setup, build, yy, levels, lcov, method, window, x, P, bias,
                                              bias_var, quad=_broad_bias_levels(setup, noise, first_start),
                                              loglik=float(res.loglik))
    if (compare and estimate) or _lag_check:
        # A covariate lag the record does not fix: states and biases averaged over it.
        x, s_var, bias, bias_var, w_lag = _lag_average(setup, dt, levels, cov, x0, P0, yy, method, window, x,
                                                       state_std**2, bias, bias_var, extra_s, extra_b)
        state_std = np.sqrt(s_var)
        corrected = y_c - bias
        warnings += w_lag
    else:
        bias_var = bias_var + extra_b
        state_std = np.sqrt(state_std**2 + extra_s)

    det, onset, alarm = _detect(build, setup, levels, yy, rows, step, false_alarm_rate, detect_shift)
    onset_t = {c: (float(tt[onset[c]]) if onset[c] >= 0 else None) for c in chans}
    alarm_t = {c: (float(tt[alarm[c]]) if alarm[c] >= 0 else None) for c in chans}
    if shift:
        x = x.copy()
        x[0] += shift
    return DriftResult(t=tt, channels=tuple(chans), corrected=corrected, bias=bias,
                       bias_std=np.sqrt(np.maximum(bias_var, 0.0)), state_names=tuple(setup.state_names),
                       state_channels=tuple(setup.state_channels),
                       state=np.asarray(x), state_std=np.asarray(state_std), onset_t=onset_t, alarm_t=alarm_t,
                       noise=tuple(noise), loglik=float(res.loglik), method=method,
                       window=int(window) if window is not None else None,
                       false_alarm_rate=float(false_alarm_rate),
                       cusum_threshold=cusum_threshold(3600.0 / (false_alarm_rate * float(np.median(dt))),
                                                       0.5 * detect_shift),
                       check=check, comparison=comparison, warnings=tuple(warnings), setup=setup)
