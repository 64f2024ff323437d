"""Monte-Carlo coverage of ``senscal drift`` (augmented-state bias Kalman filter).

Each scenario simulates records with :func:`senscal.simulate.drift.simulate_drift_batch`,
runs :func:`senscal.drift.correct_drift` on each (RTS smoother, so one fit
gives the noise levels, the pointwise bias band and the final bias: at the
last sample the smoother is the filter) and compares with the truth.

Seed counts: every record needs its own maximum-likelihood search (one to a
few hundred Kalman passes over 600 samples, about 0.3-1 s), so the full
benchmark uses 200 seeds per scenario (a Wilson interval of about +/- 4 % at
99.9 %: 90 % coverage fails), 100 for the ramp scenario that also fits the
alternative models, and CI 6-40 (enough to fail a band that covers
80 % or a warning that misses more than one seed in twenty).

The pointwise band is reported as its coverage averaged over time and
seeds; the row's ``n`` is the number of seeds (each seed counts once), which
is conservative because the time average of a seed varies less than one
Bernoulli draw.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from senscal.diagnostics import has_warning
from senscal.drift import correct_drift, covariate_setup, known_setup, redundant_setup
from senscal.simulate.drift import simulate_drift_batch
from senscal.validation import CoverageRow, coverage_row

JOB = "drift"
FULL = 200
#: Samples left out of the band's coverage at each end (in units of the
#: record): none; the smoother's band is meant to hold everywhere.
_N = 600


def _band_row(case: str, est: np.ndarray, std: np.ndarray, truth: np.ndarray, note: str,
              skip: int = 0) -> CoverageRow:
    """Pointwise band coverage averaged over time and seeds (n = seeds)."""
    z = (est[:, skip:] - truth[:, skip:]) / std[:, skip:]
    ok = np.isfinite(z)
    cov = float(np.mean(np.where(ok, np.abs(z) <= 2.0, False)))
    return CoverageRow(JOB, case, "bias band (smoother, pointwise)", int(est.shape[0]), cov,
                       float(np.std(z[ok])), note=note + "; averaged over time and seeds, n = seeds")


def _run(case: str, n_seeds: int, seed0: int, sim: dict, make_setup: Callable, note: str, *,
         levels_truth: dict | None = None, warn: tuple[str, ...] = (), expect: str = "cover",
         terms: dict | None = None, compare: bool = False) -> list[CoverageRow]:
    d = simulate_drift_batch(n_seeds, seed=seed0, **sim)
    setup = make_setup(d)
    chan = [c for c in d["channels"] if c not in d["trusted"]][0]
    i = d["channels"].index(chan)
    est, std, fin, fin_u, warned = [], [], [], [], []
    lev = {k: ([], []) for k in (levels_truth or {})}
    term = {k: ([], []) for k in (terms or {})}
    for s in range(n_seeds):
        cov = {"c": d["covariate"][s]} if d["covariate"] is not None else None
        r = correct_drift(setup, d["y"][s][[d["channels"].index(c) for c in setup.channels]], d["t"], cov,
                          smooth=True, compare=compare)
        j = r.channels.index(chan)
        est.append(r.bias[j])
        std.append(r.bias_std[j])
        fin.append(r.bias[j, -1])
        fin_u.append(r.bias_std[j, -1])
        warned.append(any(has_warning(r.warnings, w_) for w_ in warn) if warn else False)
        for p in r.noise:
            if p.name in lev:
                lev[p.name][0].append(p.value)
                lev[p.name][1].append(np.nan if p.std is None else p.std)
        for k in term:
            v, u = r.final(k)
            term[k][0].append(v)
            term[k][1].append(u)
    truth_b = d["bias"][:, i]
    w = warned if warn else None
    rows = [_band_row(case, np.array(est), np.array(std), truth_b, note),
            coverage_row(JOB, case, f"final bias of {chan}", fin, fin_u, truth_b[:, -1], warned=w, expect=expect,
                         note=note)]
    if warn:
        rows[0] = CoverageRow(**{**rows[0].__dict__, "warned": float(np.mean(warned)), "expect": expect})
    for k, (v, u) in lev.items():
        rows.append(coverage_row(JOB, case, k, v, u, levels_truth[k], warned=w, expect=expect, note=note))
    for k, (v, u) in term.items():
        rows.append(coverage_row(JOB, case, k, v, u, terms[k], warned=w, expect=expect, note=note))
    if expect == "named":
        # Covered or named, seed by seed (issue 26: ">= 95 % of seeds"): a seed passes when its k=2 interval
        # holds the truth (the band: over at least 95 % of the record) or a listed warning fired.
        wa = np.asarray(warned, dtype=bool)
        zb = np.abs((np.array(est) - truth_b) / np.array(std))
        ok = {rows[0].quantity: np.mean(np.where(np.isfinite(zb), zb <= 2.0, False), axis=1) >= 0.95,
              rows[1].quantity: np.abs(np.array(fin) - truth_b[:, -1]) <= 2.0 * np.array(fin_u)}
        for k, (v, u) in term.items():
            ok[k] = np.abs(np.array(v) - terms[k]) <= 2.0 * np.array(u)
        rows = [CoverageRow(**{**r.__dict__, "warned": float(np.mean(ok[r.quantity] | wa)), "expect": "warn",
                               "note": r.note + "; warned = covered or named, per seed"})
                if r.quantity in ok else r for r in rows]
    return rows


def run_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The filter's own model: random-walk quantity and bias, white noise."""
    sim = dict(n=_N, noise=0.1, signal="random_walk", signal_level=0.1, bias="random_walk", bias_rate=0.01)
    return _run("white", n_seeds, seed0, sim, lambda d: redundant_setup(["s1", "s2"], trusted=["s1"]),
                "redundant pair, s1 trusted, model = truth",
                levels_truth={"s1_noise_std": 0.1, "s2_noise_std": 0.1, "signal_rate_std": 0.1,
                              "s2_bias_rate_std": 0.01})


def run_gm_ramp(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Issue 14 item 1 and 4: a Gauss-Markov quantity (tau 200 s, not a
    random walk) and a ramp bias from 60 % of the record, with the ramp model
    (``bias_dynamics="ramp"``)."""
    sim = dict(n=_N, noise=0.1, signal="gauss_markov", signal_level=1.0, signal_tau=200.0, bias="ramp",
               ramp_start=300.0, ramp_slope=4e-3)
    return _run("gm-signal+ramp", n_seeds, seed0, sim,
                lambda d: redundant_setup(["s1", "s2"], trusted=["s1"], bias_dynamics="ramp"),
                "quantity Gauss-Markov tau 200 s (model: random walk), ramp bias, ramp model",
                levels_truth={"s1_noise_std": 0.1, "s2_noise_std": 0.1})


def run_ramp_rw(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The same ramp with the default random-walk bias model: the job uses
    the ramp model when the random walk's innovations are rejected and the
    ramp wins on AIC (and says so), and names it (``better-model``) when only
    AIC prefers it; the band must cover (the warning rate is reported)."""
    sim = dict(n=_N, noise=0.1, signal="gauss_markov", signal_level=1.0, signal_tau=200.0, bias="ramp",
               ramp_start=300.0, ramp_slope=4e-3)
    return _run("gm-signal+ramp, rw model", n_seeds, seed0, sim,
                lambda d: redundant_setup(["s1", "s2"], trusted=["s1"]),
                "ramp bias fitted with a random-walk bias (model chosen by the job)",
                warn=("better-model", "model-inadequate"), expect="cover", compare=True)


def run_known(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Preset ``known`` (a gyro at rest): true value 0, random-walk bias."""
    sim = dict(n=_N, channels=("g",), trusted=(), noise=0.1, signal="known", signal_mean=0.0,
               bias="random_walk", bias_rate=0.01)
    return _run("known value", n_seeds, seed0, sim, lambda d: known_setup(["g"], 0.0),
                "one sensor, true value known (0)", levels_truth={"g_noise_std": 0.1, "g_bias_rate_std": 0.01})


# One sensor of a Gauss-Markov quantity (tau 200 s) whose bias is 0.2/degC x (c - 20): shared by the covariate cases.
_COVARIATE_SIM = dict(n=_N, channels=("x",), trusted=(), noise=0.1, signal="gauss_markov", signal_level=1.0,
                      signal_tau=200.0, bias="none", covariate_coefficient=0.2)


def run_covariate(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Preset ``covariate`` with the reference given: coefficient and bias cover."""
    sim = _COVARIATE_SIM
    return _run("covariate, reference given", n_seeds, seed0, sim,
                lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0,
                                          covariate_reference=20.0),
                "one sensor, bias 0.2/degC x (c - 20), Gauss-Markov quantity with the right tau",
                terms={"x_c_coefficient": 0.2})


def run_reference_defaulted(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Issue 14 item 5: the reference left to default (the covariate mean)."""
    sim = _COVARIATE_SIM
    return _run("covariate, reference defaulted", n_seeds, seed0, sim,
                lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0),
                "bias zero at 20 degC, reference not given", warn=("covariate-reference-defaulted",),
                expect="warn")


def run_wrong_tau(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Issue 14 item 2: a Gauss-Markov quantity fitted with a tau 10x too short.

    Issue 26: the tau asked for is a starting point unless asserted
    (``tau_known``); with the comparison on, the job averages over the
    time constants the record allows, the profile likelihood as weight
    (``_tau_average`` in senscal.drift.core), so tau is in u and every row
    must cover (judged like the lag rows; ``warned`` is the share of
    records named).  Before, the result came from the tau asked for (or a
    better one where the innovations rejected it), named otherwise: judged
    per seed (covered or named) 91 / 94 / 94 % (band, final bias,
    coefficient; 200 seeds) once ``better-model`` needed an Akaike weight
    above 0.95, while the pointwise band covered 62-67 %.
    """
    sim = _COVARIATE_SIM
    return _run("covariate, wrong signal tau", n_seeds, seed0, sim,
                lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=20.0,
                                          covariate_reference=20.0),
                "quantity tau 200 s, model tau 20 s not asserted: averaged over tau by the job; warned = share named",
                warn=("model-inadequate", "better-model"), expect="cover", compare=True,
                terms={"x_c_coefficient": 0.2})


def run_known_tau(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The tau asserted (``tau_known``, ``--signal-tau-known``), right, comparison on.

    No average over tau: u is that of the model with the tau given (the
    lag is still averaged: no lag is given), which must cover.
    """
    sim = _COVARIATE_SIM
    return _run("covariate, signal tau known", n_seeds, seed0, sim,
                lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0,
                                          covariate_reference=20.0, signal_tau_known=True),
                "quantity tau 200 s asserted (no tau average), comparison on",
                warn=("covariate-lag-uncertain", "better-model", "model-inadequate"), expect="cover", compare=True,
                terms={"x_c_coefficient": 0.2})


def run_ar1_noise(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Issue 26 item 4: the drifting channel's noise is AR(1) with rho 0.8
    (same std); the job offers coloured noise as a model option chosen by
    AIC.  Before it, the bias band covered 74 % and ``model-inadequate``
    fired in 3 % of records; with it the band covered 93.1 % and the final
    bias 91.5 %, so the colour is named (``coloured-noise``): each seed
    passes when covered or named."""
    sim = dict(n=_N, noise=0.1, signal="random_walk", signal_level=0.1, bias="random_walk", bias_rate=0.01,
               noise_rho=0.8)
    return _run("coloured noise AR(1) 0.8", n_seeds, seed0, sim,
                lambda d: redundant_setup(["s1", "s2"], trusted=["s1"]),
                "redundant pair, s2's noise AR(1) rho 0.8 (model chosen by the job)",
                warn=("coloured-noise", "better-model", "model-inadequate"), expect="named", compare=True)


def _run_lag(lag: float):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        sim = dict(_COVARIATE_SIM, covariate_lag=lag)
        return _run(f"covariate lag {lag:g} s", n_seeds, seed0, sim,
                    lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0,
                                              covariate_reference=20.0),
                    f"the bias follows the covariate through a first-order lag of {lag:g} s (averaged over the "
                    "lag by the job; warned = share named)",
                    warn=("model-inadequate", "better-model", "covariate-lag-uncertain"), expect="cover",
                    compare=True, terms={"x_c_coefficient": 0.2})
    run.__doc__ = (f"Issue 26 item 5: the sensor's temperature lags the recorded probe by a first-order lag of "
                   f"{lag:g} s.  Before the job offered the lag, the coefficient covered 15-62 % for lags of "
                   "3-60 s; with the states averaged over the lag's likelihood (``_lag_average`` in "
                   "senscal.drift.core) the lag is in u, so every row must cover (judged like the lag-free "
                   "rows; ``warned`` is the share of records named).  Judged per seed (covered over >= 95 % "
                   "of the record, or named) the band passed in 91 % of 100 seeds, the same share as on "
                   "lag-free records with the model asked for true: a correct pointwise band does not cover "
                   "95 % of every record.")
    return run


run_lag3, run_lag20, run_lag60 = _run_lag(3.0), _run_lag(20.0), _run_lag(60.0)


def run_lag0(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The lag check's false alarms: the same one-sensor records with no lag.

    The model asked for is the truth, so everything covers; ``warned`` is
    the share of records named ``covariate-lag-uncertain`` (or
    ``better-model`` / ``model-inadequate``), a false alarm that makes
    ``--strict`` refuse a good record.  Issue 26 item 5: the former lag
    check (a lag inside its 95 % profile interval moving the result by
    more than u) named a lag in 59 % of these records and ``better-model``
    (AIC margin 0) fired in 31 % (100 seeds); with the lag averaged into u
    and the name kept for lag 0 rejected at 95 %, and ``better-model`` at
    an Akaike weight above 0.95, 1 % of 100 seeds were named (6.5 % of
    200).  With the signal tau averaged over too (not asserted here),
    96.0-96.6 % cover and 6 % are named (200 seeds).
    """
    rows = _run("covariate lag 0 s", n_seeds, seed0, _COVARIATE_SIM,
                lambda d: covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0,
                                          covariate_reference=20.0),
                "no lag (model = truth, comparison on): coverage, and how often a lag is named",
                warn=("covariate-lag-uncertain", "better-model", "model-inadequate"), expect="cover",
                compare=True, terms={"x_c_coefficient": 0.2})
    return rows + [_quiet_row(rows[0], "lag-free")]


def _quiet_row(row: CoverageRow, what: str) -> CoverageRow:
    """The false alarms as a row of their own: with the model asked for true, "no named
    warning" should hold in 95 % of records (the checks are 5 % tests), judged by the
    coverage rule."""
    return CoverageRow(JOB, row.case, "no warning (false-alarm check)", row.n, 1.0 - row.warned, float("nan"),
                       note=f"share of {what} records without the scenario's named warnings; 5 % tests keep 95 %")


def run_white_compare(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """The white records with the comparison on (the job's default): coverage, and how
    often coloured noise (or a better model) is named where the noise is white."""
    sim = dict(n=_N, noise=0.1, signal="random_walk", signal_level=0.1, bias="random_walk", bias_rate=0.01)
    rows = _run("white, comparison on", n_seeds, seed0, sim, lambda d: redundant_setup(["s1", "s2"], trusted=["s1"]),
                "redundant pair, s1 trusted, model = truth, alternatives fitted",
                warn=("coloured-noise", "model-inadequate"), expect="cover", compare=True)
    return rows + [_quiet_row(rows[0], "white-noise")]


for _f in (run_white, run_gm_ramp, run_known, run_covariate, run_reference_defaulted):
    _f.full_seeds = FULL
# Warn-only scenarios whose every record also fits the alternative models
# (two to four more likelihood searches): 100 seeds put the warning rate
# within +/- 5 % (99.9 % Wilson) at a third of the cost.
run_ramp_rw.full_seeds = 100
# The issue-26 departures: the rule asks for >= 200 seeds.
for _f in (run_wrong_tau, run_ar1_noise, run_white_compare, run_lag0, run_lag3, run_lag20, run_lag60,
           run_known_tau):
    _f.full_seeds = FULL

SCENARIOS = {"white": run_white, "gm-signal+ramp": run_gm_ramp, "ramp-rw-model": run_ramp_rw, "known": run_known,
             "covariate": run_covariate, "reference-defaulted": run_reference_defaulted,
             "wrong-tau": run_wrong_tau, "known-tau": run_known_tau, "ar1-noise": run_ar1_noise,
             "white-compare": run_white_compare,
             "covariate-lag-0": run_lag0,
             "covariate-lag-3": run_lag3,
             "covariate-lag-20": run_lag20, "covariate-lag-60": run_lag60}
