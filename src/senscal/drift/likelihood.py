"""The drift model's log-likelihood and its score over log noise levels, in one compiled pass.

Maximum-likelihood estimation of the noise levels evaluates the Kalman
likelihood tens of times.  :class:`LevelLikelihood` builds the model's raw
matrices for a set of levels (no validation: the levels come from the
optimiser, the structure was checked once) together with their derivatives
with respect to the log of each free level, and runs
:func:`senscal.kalman._score.score_series`: ``ln L`` and its gradient from
one pass (sensitivity equations), with the steady-state gain once the
covariance and its derivatives have converged (uniform sampling, no
covariate, no gaps).

Derivatives of the matrices: a variance enters ``Q``, ``R`` (and a
coloured-noise state's stationary prior) linearly in ``level^2``, so
``d/d ln(level) = 2 level^2 x`` (its unit-level block); a time constant
(coloured-noise ``tau``, covariate ``lag``) moves ``F``, ``Q`` or ``H``
non-linearly and is differentiated by central differences of the matrices
(step 1e-4 in ln tau: relative error ~1e-8, far below what the optimiser
resolves).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from senscal.drift.model import DriftSetup, _scalar_dynamics, augmented_arrays, lag_filter
from senscal.kalman._score import score_series, score_series_scalar

__all__ = ["LevelLikelihood"]

_H_LOG = 1e-4


class LevelLikelihood:
    """``ln L`` and ``d ln L / d ln(level)`` of a drift set-up for given data.

    Parameters
    ----------
    setup : DriftSetup
    dt : ndarray, (1,) or (T,)
        Steps [s] as :func:`senscal.drift.model._uniform_dt` gives them (one
        value when uniform).
    y : ndarray, (m, T)
        Measurements (already minus a known mean), NaN = missing.
    covariates : mapping of str to ndarray (T,)
        Referenced covariates.
    x0, P0 : ndarray
        Prior of the augmented state.
    names : sequence of str
        The free levels, in the order of the gradient.
    """

    def __init__(self, setup: DriftSetup, dt: np.ndarray, y: np.ndarray, covariates: Mapping[str, np.ndarray],
                 x0: np.ndarray, P0: np.ndarray, names: Sequence[str]) -> None:
        self.setup = setup
        self.dt = dt
        self.cov = covariates
        self.x0, self.P0 = x0, P0
        self.names = list(names)
        self.y = np.ascontiguousarray(np.asarray(y, dtype=float).T)
        self.T = self.y.shape[0]
        self.allow_ss = bool(dt.size == 1 and not setup.covariates and not np.isnan(self.y).any())
        ns = setup.signal.n_states
        nb_ = setup.n_bias_states
        self._ar_index = {c: ns + nb_ + i for i, c in enumerate(setup.ar_noise)}
        self.kind = {}
        for k in self.names:
            if k.endswith("_noise_std") and k[: -len("_noise_std")] in setup.channels:
                self.kind[k] = "R"
            elif k.endswith("_noise_ar_tau") or k.endswith("_lag"):
                self.kind[k] = "NL"
            else:
                self.kind[k] = "Q"
        self._has_nl = any(v == "NL" for v in self.kind.values())
        self._moves_f = np.array([k.endswith("_noise_ar_tau") for k in self.names], dtype=np.bool_)
        self._moves_h = np.array([k.endswith("_lag") for k in self.names], dtype=np.bool_)
        # A known quantity's states are held at their value (zero prior and
        # process variance): exactly nothing, so they are left out of the pass.
        n = len(setup.state_names)
        self._keep = np.arange(ns, n) if setup.signal.kind == "known" else np.arange(n)
        self._parts_key = None
        self._parts = None
        self._bufs: dict = {}
        # Where each time constant acts (positions in the kept states): a
        # coloured-noise tau moves only its state's F and Q entries (and the
        # unit of its std, which is free beside it), a lag only its bias's H
        # column.  A new time constant then rewrites those entries instead of
        # building the model again (each build is a few (T, n, n) stacks).
        pos = {int(i): j for j, i in enumerate(self._keep)}
        full = list(setup.state_names)
        self._nl_at: dict[str, tuple] = {}
        for k in self.names:
            if k.endswith("_noise_ar_tau"):
                c = k[: -len("_noise_ar_tau")]
                std = f"{c}_noise_ar_std"
                if std in self.kind and self.kind[std] == "Q":
                    self._nl_at[k] = ("tau", pos[full.index(f"{c}_noise_ar")], std)
            elif k.endswith("_lag"):
                b = next((b for b in setup.biases if b.lag_name == k), None)
                if b is not None:
                    self._nl_at[k] = ("lag", setup.channels.index(b.channel), pos[full.index(b.name)],
                                      b.covariate)
        self._patch = all(self._nl_at.get(k) is not None for k in self.names if self.kind[k] == "NL")
        #: Expected information over ln(level) of the last call with the gradient.
        self.info = None

    def _raw(self, levels: Mapping[str, float]):
        F, H, Q, R, x0, P0 = augmented_arrays(self.setup, self.dt, levels, self.cov, x0=self.x0, P0=self.P0, T=self.T)
        k = self._keep
        if k.size != F.shape[1]:
            F, Q, H = F[:, k][:, :, k], Q[:, k][:, :, k], H[:, :, k]
            x0, P0 = x0[k], P0[np.ix_(k, k)]
        return F, H, Q, R, x0, P0

    def _linear(self, levels: Mapping[str, float]):
        """F, H, x0 and the parts of Q, R, P0 linear in the squared variance levels, at these time constants.

        ``Q = Q_0 + sum_k level_k^2 U_k`` (likewise R, P0) over the free
        variance levels: the model is then assembled by a few additions, and
        ``2 level_k^2 U_k`` is its derivative over ``ln(level_k)``.
        """
        key = tuple(float(levels[k]) for k in self.names if self.kind[k] == "NL")
        if key == self._parts_key:
            return self._parts
        if self._patch and self._parts is not None:
            # Only the time constants changed: rewrite the entries they move,
            # with the very expressions augmented_arrays evaluates (same numbers).
            F, H, x0, Q0, R0, P00, units = self._parts
            nl = [k for k in self.names if self.kind[k] == "NL"]
            old_key, self._parts_key = self._parts_key, None
            try:
                for k, v, old in zip(nl, key, old_key):
                    if v != old:
                        at = self._nl_at[k]
                        if at[0] == "tau":
                            Fa, Qa = _scalar_dynamics("gauss_markov", self.dt, 1.0, v)
                            F[:, at[1], at[1]] = Fa[:, 0, 0]
                            units[at[2]][0][:, at[1], at[1]] = Qa[:, 0, 0]
                        else:
                            H[:, at[1], at[2]] = self._lagged(at[3], v)
            except BaseException:
                # Half rewritten: build anew next time.
                self._parts = None
                raise
            self._parts_key = key
            return self._parts
        lin = [k for k in self.names if self.kind[k] != "NL"]
        zero = dict(levels)
        zero.update({k: 0.0 for k in lin})
        F, H, Q0, R0, x0, P00 = self._raw(zero)
        units = {}
        for k in lin:
            one = dict(zero)
            one[k] = 1.0
            _, _, Qk, Rk, _, Pk = self._raw(one)
            units[k] = (Qk - Q0, Rk - R0, Pk - P00)
        self._parts_key, self._parts = key, (F, H, x0, Q0, R0, P00, units)
        return self._parts

    def _lagged(self, covariate: str, lag: float) -> np.ndarray:
        """The covariate through its first-order lag, as augmented_arrays puts it into H."""
        return lag_filter(self.cov[covariate], self.dt, lag) if lag > 0 else self.cov[covariate]

    def _buffer(self, name: str, shape: tuple) -> np.ndarray:
        """A zeroed array kept for the next pass.

        Passes over a long record would otherwise allocate (and fault in)
        tens of MB each.  Each derivative row is written at the same entries
        on every pass (by its level's kind), so entries left zero stay zero.
        """
        key = (name, shape)
        buf = self._bufs.get(key)
        if buf is None:
            buf = self._bufs[key] = np.zeros(shape)
        return buf

    def _assemble(self, levels: Mapping[str, float]):
        F, H, x0, Q0, R0, P00, units = self._linear(levels)
        Q = self._buffer("Q", Q0.shape)
        np.copyto(Q, Q0)
        R, P0 = R0.copy(), P00.copy()
        tmp = self._buffer("tmp", Q0.shape)
        for k, (Qk, Rk, Pk) in units.items():
            v2 = float(levels[k]) ** 2
            if self.kind[k] == "R":
                R += v2 * Rk
            else:
                # Q += v2 * Qk without the temporaries (the same operations).
                np.multiply(Qk, v2, out=tmp)
                np.add(Q, tmp, out=Q)
                P0 += v2 * Pk
        return F, H, Q, R, x0, P0, units

    def __call__(self, levels: Mapping[str, float], grad: bool = True) -> tuple[float, np.ndarray]:
        """``(ln L, gradient over ln(level) of self.names)``; ln L is NaN for an invalid model."""
        F, H, Q, R, x0, P0, units = self._assemble(levels)
        p = len(self.names)
        n, m = F.shape[1], H.shape[1]
        useF = self._moves_f if grad else np.zeros(p, dtype=np.bool_)
        useH = self._moves_h if grad else np.zeros(p, dtype=np.bool_)
        dF = self._buffer("dF" if grad else "dF0", (p, F.shape[0] if useF.any() else 1, n, n))
        dH = self._buffer("dH" if grad else "dH0", (p, H.shape[0] if useH.any() else 1, m, n))
        dQ = self._buffer("dQ" if grad else "dQ0", (p, Q.shape[0] if grad else 1, n, n))
        dR = np.zeros((p, 1, m, m))
        dP0 = np.zeros((p, n, n))
        if grad:
            for i, k in enumerate(self.names):
                if self.kind[k] != "NL":
                    Qk, Rk, Pk = units[k]
                    v2 = 2.0 * float(levels[k]) ** 2
                    if self.kind[k] == "R":
                        dR[i] = v2 * Rk
                    else:
                        np.multiply(Qk, v2, out=dQ[i])
                        dP0[i] = v2 * Pk
                    continue
                v = float(levels[k])
                at = self._nl_at.get(k) if self._patch else None
                if at is not None:
                    # The central differences of the entries the time constant moves
                    # (the rest of the two models is equal, so their differences are 0).
                    vu, vd = v * np.exp(_H_LOG), v * np.exp(-_H_LOG)
                    if at[0] == "tau":
                        std = float(levels[at[2]])
                        Fu, Qu = _scalar_dynamics("gauss_markov", self.dt, std, vu)
                        Fd, Qd = _scalar_dynamics("gauss_markov", self.dt, std, vd)
                        dQ[i][:, at[1], at[1]] = (Qu[:, 0, 0] - Qd[:, 0, 0]) / (2 * _H_LOG)
                        if useF[i]:
                            dF[i][:, at[1], at[1]] = (Fu[:, 0, 0] - Fd[:, 0, 0]) / (2 * _H_LOG)
                    elif useH[i]:
                        dH[i][:, at[1], at[2]] = (self._lagged(at[3], vu) - self._lagged(at[3], vd)) / (2 * _H_LOG)
                    continue
                up = dict(levels)
                dn = dict(levels)
                up[k] = v * np.exp(_H_LOG)
                dn[k] = v * np.exp(-_H_LOG)
                # Whole models at the two time constants (two builds, the linear parts stay cached).
                Fu, Hu, Qu, _, _, Pu = self._raw(up)
                Fd, Hd, Qd, _, _, Pd = self._raw(dn)
                dQ[i] = (Qu - Qd) / (2 * _H_LOG)
                dP0[i] = (Pu - Pd) / (2 * _H_LOG)
                if useF[i]:
                    dF[i] = (Fu - Fd) / (2 * _H_LOG)
                if useH[i]:
                    dH[i] = (Hu - Hd) / (2 * _H_LOG)
        # The frozen gain needs every matrix and derivative constant in time.
        allow = self.allow_ss and max(F.shape[0], H.shape[0], Q.shape[0], dF.shape[1], dH.shape[1], dQ.shape[1]) == 1
        # One channel (a known quantity's channel, a sensor with a covariate): the scalar kernel, same numbers.
        kernel = score_series_scalar if m == 1 else score_series
        ll, g, info, _ = kernel(F, H, Q, R, x0, P0, self.y, dF, dH, dQ, dR, dP0, useF, useH, bool(allow), grad)
        self.info = info
        return float(ll), g
