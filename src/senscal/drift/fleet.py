"""Drift correction for fleets: thousands of channels, chunk by chunk, on Dask.

A *fleet* is a Parquet dataset (a folder of files, each a block of channels
with a time column ``t`` [s], cut into row groups) and a configuration of
channel *groups*: one drift set-up per group with known noise levels (a
gyro at rest with a random-walk bias, a sensor with a temperature-linked
bias, ...), applied to every channel the group's patterns name.  Each
channel is an independent instance of its group's one-channel set-up.

:func:`run_fleet` processes every (file, group) *block* as one task: the
row groups in time order, all channels of the block at once, the state of
every channel (filtered mean and covariance) written to the *state store*
after every row group, atomically, so that a crash loses at most the row
group in flight and the next run continues where the store stops (rows at
or before a channel's stored time are skipped).  Blocks run in parallel on
a ``dask.distributed`` client, or one after another in this process.

Two compiled kernels do the filtering, both the recursion of
:func:`senscal.kalman.kalman_filter` (Joseph-form update):

* *shared*: when the channels of a block share set-up, levels, sampling,
  prior and missing-sample pattern and no covariate enters ``H``, their
  covariances (hence gains) are equal: the Riccati recursion runs once and
  each channel only updates its mean (``n^2 + 2n`` flops a sample);
* *per channel*: otherwise (per-channel levels, covariates, missing
  samples) each channel carries its own covariance.

Both give, to rounding, what :class:`senscal.drift.stream.DriftTracker`
gives channel by channel.

Units: time in s; levels as in :mod:`senscal.drift.model` (random-walk
rates in unit/sqrt(s), standard deviations in unit).
"""

from __future__ import annotations

import fnmatch
import math
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numba as nb
import numpy as np

from senscal.diagnostics import named
from senscal.drift.model import DriftSetup, augmented_model, covariate_setup, known_setup, load_model_yaml
from senscal.errors import DataError, FileFormatError, InputError
from senscal.jobs._base import JobResult
from senscal.kalman import _kernels as KK
from senscal.quantity import Quantity

__all__ = ["FleetGroup", "FleetBlock", "FleetOptions", "FleetResult", "ChannelState", "load_fleet_config",
           "fleet_groups", "plan_blocks", "run_fleet", "fleet", "read_store", "filter_block", "FORMAT_VERSION",
           "ROLE"]

#: Version of the state store layout (``<group>--<file>.npz`` per block).
FORMAT_VERSION = 1
#: Name of the measured channel inside a group's one-channel set-up (``y_noise_std`` ...).
ROLE = "y"


# --------------------------------------------------------------------------- configuration

@dataclass(frozen=True)
class FleetGroup:
    """Channels that share one drift set-up.

    Parameters
    ----------
    name : str
        Group name (the state store and results name it).
    setup : DriftSetup
        One measured channel called ``ROLE`` (``"y"``); covariate-linked
        biases need their ``reference`` (a stream has no record mean).
    levels : mapping of str to float
        Every noise level of ``setup.level_names()`` (``y_noise_std`` [unit],
        ``y_bias_rate_std`` [unit/sqrt(s)], ...).
    channels : tuple of str
        Dataset columns of the group: names or shell patterns (``gyro_*``).
    covariate_column : str
        Column of a channel's covariate: ``{channel}`` and ``{covariate}``
        are replaced (default ``{channel}.{covariate}``).
    channel_levels : mapping of str to mapping, optional
        Per-channel overrides of ``levels``.
    prior_scale : float, optional
        Typical size of the quantity's deviation and of the biases [unit]:
        the prior widths of every channel (``drift_prior`` with this
        spread), so that the group's channels share their covariance and
        the fast shared kernel applies.  None: each channel's spread over
        its first chunk, as :class:`~senscal.drift.stream.DriftTracker`
        does by default.
    """

    name: str
    setup: DriftSetup
    levels: Mapping[str, float]
    channels: tuple[str, ...] = ("*",)
    covariate_column: str = "{channel}.{covariate}"
    channel_levels: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    prior_scale: float | None = None

    def __post_init__(self) -> None:
        if self.prior_scale is not None and not (math.isfinite(self.prior_scale) and self.prior_scale > 0):
            raise InputError(f"fleet group {self.name}: prior_scale must be a number > 0 [unit], got {self.prior_scale}")
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "levels", {k: float(v) for k, v in dict(self.levels).items()})
        if not self.name or "--" in self.name or "/" in self.name:
            raise InputError(f"fleet group name {self.name!r} must be non-empty, without '/' or '--'")
        if tuple(self.setup.channels) != (ROLE,):
            raise InputError(f"the set-up of fleet group {self.name} must measure one channel named {ROLE!r} "
                             f"(each fleet channel is one instance of it), got {list(self.setup.channels)}")
        need = self.setup.level_names()
        for lv in [self.levels, *self.channel_levels.values()]:
            bad = [k for k in lv if k not in need]
            if bad:
                raise InputError(f"fleet group {self.name}: unknown noise levels {bad}; its set-up has {need}")
        missing = [k for k in need if k not in {**self.setup.given_levels(), **self.levels}]
        if missing:
            raise InputError(f"fleet group {self.name} needs the noise levels {missing} (a fleet run does not "
                             "estimate them; fit them on one channel with senscal drift --json, or from Allan "
                             "deviation)")
        for k, v in {**self.levels, **{k: v for lv in self.channel_levels.values() for k, v in lv.items()}}.items():
            if not (math.isfinite(v) and v >= 0) or (k.endswith("_noise_std") and not v > 0):
                raise InputError(f"fleet group {self.name}: noise level {k} must be a finite number "
                                 f"{'> 0' if k.endswith('_noise_std') else '>= 0'}, got {v}")
        for b in self.setup.biases:
            if b.covariate is not None and b.reference is None:
                raise InputError(f"fleet group {self.name}: the {b.covariate} bias needs a reference value "
                                 f"(reference: in the set-up); a stream has no record mean to default to")

    def all_levels(self, channel: str | None = None) -> dict[str, float]:
        """Levels of ``channel``: the set-up's given ones, the group's, then the channel's overrides."""
        out = {**self.setup.given_levels(), **self.levels}
        if channel is not None:
            out.update(self.channel_levels.get(channel, {}))
        return out

    def matches(self, column: str) -> bool:
        return any(fnmatch.fnmatchcase(column, p) for p in self.channels)

    def covariate_columns(self, channel: str) -> tuple[str, ...]:
        return tuple(self.covariate_column.format(channel=channel, covariate=c) for c in self.setup.covariates)


_PRESET_KEYS = {"known": {"preset", "value", "bias_dynamics", "bias_tau", "covariate", "reference"},
                "covariate": {"preset", "covariate", "reference", "signal", "signal_tau", "signal_mean"}}


def _setup_from(doc: Any, group: str, base: Path) -> DriftSetup:
    if isinstance(doc, str):
        return load_model_yaml(base / doc)
    if not isinstance(doc, dict) or doc.get("preset") not in _PRESET_KEYS:
        raise FileFormatError(f"fleet group {group}: setup must be a model file name or a mapping with preset: "
                              f"known or covariate")
    preset = doc["preset"]
    bad = set(doc) - _PRESET_KEYS[preset]
    if bad:
        raise FileFormatError(f"fleet group {group}: unknown setup keys {sorted(bad)} for preset {preset}; "
                              f"allowed: {sorted(_PRESET_KEYS[preset])}")
    if preset == "known":
        return known_setup([ROLE], float(doc.get("value", 0.0)), bias_dynamics=doc.get("bias_dynamics", "random_walk"),
                           bias_tau=doc.get("bias_tau"), covariate=doc.get("covariate"),
                           covariate_reference=doc.get("reference"))
    if "covariate" not in doc:
        raise FileFormatError(f"fleet group {group}: preset covariate needs covariate: NAME")
    return covariate_setup(ROLE, doc["covariate"], signal=doc.get("signal", "random_walk"),
                           signal_tau=doc.get("signal_tau"), signal_mean=float(doc.get("signal_mean", 0.0)),
                           covariate_reference=doc.get("reference"))


def load_fleet_config(path: str | Path) -> tuple[FleetGroup, ...]:
    """Read a fleet configuration (JSON or YAML).

    Layout::

        groups:
          - name: gyros
            channels: ["g*"]                 # names or patterns (default: every column)
            setup: {preset: known, value: 0.0, bias_dynamics: random_walk}
            levels: {y_noise_std: 0.05, y_bias_rate_std: 2.0e-4}
            channel_levels: levels.csv       # optional: a 'channel' column + level columns
          - name: thermal
            channels: ["p*"]
            setup: {preset: covariate, covariate: temperature, reference: 20.0}
            covariate_column: "{channel}.{covariate}"
            levels: {y_noise_std: 0.05, signal_rate_std: 1.0e-3, y_temperature_coefficient_rate_std: 2.0e-5}

    ``setup`` may also name a drift model YAML (one channel ``y``, see
    :func:`senscal.drift.load_model_yaml`), relative to this file.

    Returns
    -------
    tuple of FleetGroup
    """
    from senscal.io.sidefiles import read_json, read_yaml

    path = Path(path)
    doc = read_json(path, "fleet configuration") if path.suffix.lower() == ".json" else read_yaml(
        path, "fleet configuration")
    if not isinstance(doc.get("groups"), list) or not doc["groups"]:
        raise FileFormatError(f"fleet configuration {path} needs a non-empty list 'groups' (see docs/drift.md#fleet)")
    return fleet_groups(doc, base=path.parent, source=str(path))


def fleet_groups(doc: Mapping[str, Any], *, base: Path | str = ".", source: str = "fleet configuration"
                 ) -> tuple[FleetGroup, ...]:
    """Groups of a configuration document already read (see :func:`load_fleet_config`)."""
    base = Path(base)
    groups = []
    for i, g in enumerate(doc.get("groups") or []):
        if not isinstance(g, dict):
            raise FileFormatError(f"{source}: group {i} must be a mapping")
        bad = set(g) - {"name", "channels", "setup", "levels", "channel_levels", "covariate_column"}
        if bad:
            raise FileFormatError(f"{source}: group {g.get('name', i)} has unknown keys {sorted(bad)}")
        name = str(g.get("name", f"group{i}"))
        chans = g.get("channels", ["*"])
        chans = [chans] if isinstance(chans, str) else list(chans)
        per = g.get("channel_levels") or {}
        if isinstance(per, str):
            per = _read_channel_levels(base / per, name)
        try:
            groups.append(FleetGroup(name=name, setup=_setup_from(g.get("setup"), name, base),
                                     levels=dict(g.get("levels") or {}), channels=tuple(str(c) for c in chans),
                                     covariate_column=str(g.get("covariate_column", "{channel}.{covariate}")),
                                     channel_levels={str(k): dict(v) for k, v in per.items()}))
        except (TypeError, ValueError) as exc:
            raise FileFormatError(f"{source}: group {name}: {exc}") from None
    names = [g.name for g in groups]
    if len(set(names)) != len(names):
        raise FileFormatError(f"{source}: group names repeat among {names}")
    return tuple(groups)


def _read_channel_levels(path: Path, group: str) -> dict[str, dict[str, float]]:
    import pandas as pd

    from senscal.io.guard import note_input

    note_input(path)
    try:
        df = pd.read_csv(path)
    except FileNotFoundError:
        raise FileFormatError(f"channel levels file {path} of group {group} does not exist") from None
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"cannot read channel levels file {path}: {exc}") from None
    if "channel" not in df.columns:
        raise FileFormatError(f"channel levels file {path} needs a 'channel' column and one column per level")
    return {str(r["channel"]): {k: float(v) for k, v in r.items() if k != "channel" and v == v}
            for r in df.to_dict("records")}


# --------------------------------------------------------------------------- the model of a group

@dataclass(frozen=True)
class _GroupModel:
    """What the kernels need of a group: the pieces of ``augmented_model`` that do not depend on the data."""

    params: tuple[str, ...]       # process-noise levels, the order of lev2's columns
    cov_cols: np.ndarray          # (k,) state index scaled by each covariate
    h0: np.ndarray                # (n,) measurement row without covariates
    bias_mask: np.ndarray         # (n,) 1 for the states that make up the channel's bias
    shift: float                  # known signal mean subtracted from y

    def matrices(self, setup: DriftSetup, dts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """F (1|T, n, n) and unit-level process noises Qu (p, 1|T, n, n) for the steps ``dts`` [s].

        ``dts[j]`` is the step into sample ``j``; ``Q = sum_p level_p^2 Qu_p``.
        """
        # augmented_model ignores the step into its first sample: give it a dummy one.
        ext = np.concatenate([dts[:1], dts])
        unit = {k: 1.0 for k in setup.level_names()}
        cov = {c: np.zeros(ext.size) for c in setup.covariates}

        def take(A: np.ndarray) -> np.ndarray:
            return A[None] if A.ndim == 2 else A[1:]

        zero = {**unit, **{p: 0.0 for p in self.params}}
        F = take(augmented_model(setup, ext, zero, cov).F)
        Qu = [take(augmented_model(setup, ext, {**zero, p: 1.0}, cov).Q) for p in self.params]
        if not Qu:
            Qu = [np.zeros_like(F[:1])]
        T1 = max(q.shape[0] for q in Qu)
        return np.ascontiguousarray(F), np.ascontiguousarray(np.stack([np.broadcast_to(q, (T1,) + q.shape[1:])
                                                                       for q in Qu]))


def _group_model(group: FleetGroup) -> _GroupModel:
    setup = group.setup
    params = tuple(k for k in setup.level_names() if not k.endswith("_noise_std"))
    ns = setup.signal.n_states
    n = len(setup.state_names)
    h0 = np.zeros(n)
    h0[:ns] = 1.0 if setup.signal.kind != "matrix" else np.asarray(setup.signal.H, dtype=float).reshape(-1)
    mask = np.zeros(n)
    cov_cols = []
    j = ns
    for b in setup.biases:
        mask[j] = 1.0
        if b.covariate is None:
            h0[j] = 1.0
        else:
            cov_cols.append(j)
        j += len(b.state_names)
    shift = setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else 0.0
    return _GroupModel(params=params, cov_cols=np.asarray(cov_cols, dtype=np.int64), h0=h0, bias_mask=mask,
                       shift=float(shift))


# --------------------------------------------------------------------------- kernels

@nb.njit(cache=True)
def _step_cov(Ft, Qt, P, Pp, tmp):
    """Pp = Ft P Ft^T + Qt (the engine's order of operations)."""
    KK._mm(Ft, P, tmp)
    Pp[:, :] = Qt
    KK._abt_sym(tmp, Ft, Ft.shape[0], Pp, True)


@nb.njit(cache=True)
def _update_cov(Pp, h, r2, P, K, IKH, KR, tmp):
    """Gain and Joseph-form update of one scalar measurement; returns S (or -1 if not > 0)."""
    n = Pp.shape[0]
    S = r2
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += Pp[i, j] * h[j]
        K[i] = acc
        S += h[i] * acc
    if not S > 0.0:
        return -1.0
    for i in range(n):
        K[i] = K[i] / S
    for i in range(n):
        for j in range(n):
            IKH[i, j] = (1.0 if i == j else 0.0) - K[i] * h[j]
        KR[i, 0] = K[i] * r2
    KK._mm(IKH, Pp, tmp)
    KK._abt_sym(tmp, IKH, n, P, False)
    for i in range(n):
        for j in range(i + 1):
            a = P[i, j] + KR[i, 0] * K[j]
            P[i, j] = a
            P[j, i] = a
    return S


@nb.njit(cache=True)
def _filter_channels(F, Qu, lev2, r2, h0, cov_cols, cov, y, shift, x, P, started, mask, bias, bvar):
    """Per-channel covariances: every channel its own Riccati recursion.

    F (1|T, n, n); Qu (p, 1|T, n, n); lev2 (C, p) squared levels; r2 (C,)
    noise variances; h0 (n,); cov_cols (k,); cov (C, k, T) referenced
    covariates; y (C, T) with NaN = missing; x (C, n), P (C, n, n), started
    (C,) updated in place (a channel not started holds its prior in x, P);
    outputs bias, bvar (C, T).  Returns the index of
    the first channel whose innovation variance was not positive, else -1.
    """
    C, T = y.shape
    n = h0.shape[0]
    npar = Qu.shape[0]
    k = cov_cols.shape[0]
    Q = np.empty((n, n))
    Pp = np.empty((n, n))
    Pc = np.empty((n, n))
    tmp = np.empty((n, n))
    IKH = np.empty((n, n))
    KR = np.empty((n, 1))
    K = np.empty(n)
    h = np.empty(n)
    xp = np.empty(n)
    for c in range(C):
        Pc[:, :] = P[c]
        for t in range(T):
            if not started[c]:
                # First sample: the prior is its predicted state, as in a one-pass run.
                xp[:] = x[c]
                Pp[:, :] = Pc
                started[c] = True
            else:
                Ft = KK._at(F, t)
                tq = 0 if Qu.shape[1] == 1 else t
                for i in range(n):
                    for j in range(n):
                        acc = 0.0
                        for p in range(npar):
                            acc += lev2[c, p] * Qu[p, tq, i, j]
                        Q[i, j] = acc
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += Ft[i, j] * x[c, j]
                    xp[i] = acc
                _step_cov(Ft, Q, Pc, Pp, tmp)
            h[:] = h0
            for j in range(k):
                h[cov_cols[j]] = cov[c, j, t]
            yv = y[c, t] - shift
            if math.isnan(yv):
                x[c, :] = xp
                Pc[:, :] = Pp
            else:
                v = yv
                for i in range(n):
                    v -= h[i] * xp[i]
                if _update_cov(Pp, h, r2[c], Pc, K, IKH, KR, tmp) < 0.0:
                    return c
                for i in range(n):
                    x[c, i] = xp[i] + K[i] * v
            b = 0.0
            bv = 0.0
            for i in range(n):
                if mask[i] != 0.0:
                    b += h[i] * x[c, i]
                    for j in range(n):
                        if mask[j] != 0.0:
                            bv += h[i] * Pc[i, j] * h[j]
            bias[c, t] = b
            bvar[c, t] = bv
        P[c] = Pc
    return -1


@nb.njit(cache=True)
def _filter_shared(F, Q, r2, h0, y, shift, x, P, started, mask, bias, bvar):
    """Shared covariance: one Riccati recursion, then each channel's mean.

    Same arguments as :func:`_filter_channels` for one set of levels: Q
    (1|T, n, n), r2 a float, P (n, n) and started a bool shared by all
    channels; y must have no NaN.  Returns (started, ok) and fills bvar (T,).
    """
    C, T = y.shape
    n = h0.shape[0]
    G = np.empty((T, n))         # gain of each step
    Pp = np.empty((n, n))
    tmp = np.empty((n, n))
    IKH = np.empty((n, n))
    KR = np.empty((n, 1))
    K = np.empty(n)
    first = not started
    for t in range(T):
        if t == 0 and first:
            Pp[:, :] = P
        else:
            _step_cov(KK._at(F, t), KK._at(Q, t), P, Pp, tmp)
        if _update_cov(Pp, h0, r2, P, K, IKH, KR, tmp) < 0.0:
            return False
        G[t] = K
        bv = 0.0
        for i in range(n):
            for j in range(n):
                bv += mask[i] * h0[i] * P[i, j] * h0[j] * mask[j]
        bvar[t] = bv
    xp = np.empty(n)
    for c in range(C):
        for t in range(T):
            if t == 0 and first:
                xp[:] = x[c]
            else:
                Ft = KK._at(F, t)
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += Ft[i, j] * x[c, j]
                    xp[i] = acc
            v = y[c, t] - shift
            for i in range(n):
                v -= h0[i] * xp[i]
            b = 0.0
            for i in range(n):
                x[c, i] = xp[i] + G[t, i] * v
                b += mask[i] * h0[i] * x[c, i]
            bias[c, t] = b
    return True


@dataclass(frozen=True)
class ChannelState:
    """Filter state of one channel after the samples seen so far.

    Attributes
    ----------
    x : ndarray, (n,)
        Filtered augmented state (``setup.state_names``; deviation from the
        known mean for a ``known`` / Gauss-Markov signal).
    P : ndarray, (n, n)
        Its covariance.
    t_last : float
        Time of the last sample filtered [s].
    n_samples : int
        Samples filtered so far (all runs).
    x0, P0 : ndarray
        The prior the channel started from (kept for
        :meth:`tracker_state`).
    """

    x: np.ndarray
    P: np.ndarray
    t_last: float
    n_samples: int
    x0: np.ndarray
    P0: np.ndarray

    def tracker_state(self, group: FleetGroup):
        """The same state as a :class:`~senscal.drift.stream.TrackerState` (continue one channel alone)."""
        from senscal.drift.stream import DriftTracker

        base = DriftTracker(group.setup, group.levels, prior=(self.x0, self.P0)).state
        return replace(base, t_last=float(self.t_last), x=np.array(self.x), P=np.array(self.P),
                       n_samples=int(self.n_samples), n_emitted=int(self.n_samples))


def channel_prior(group: FleetGroup, y: np.ndarray, t: np.ndarray, covariates: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Prior of one channel from its first chunk: :func:`~senscal.drift.core.drift_prior` with the group's spread.

    Parameters
    ----------
    group : FleetGroup
    y : ndarray, (T,)
        The channel's first chunk [unit].
    t : ndarray, (T,)
        Its time [s].
    covariates : ndarray, (k, T), optional
        Its raw covariates (``group.setup.covariates`` order).

    Returns
    -------
    x0 : ndarray, (n,)
    P0 : ndarray, (n, n)
    """
    from senscal.drift.core import drift_prior

    setup = group.setup
    shift = setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else 0.0
    refs = {b.covariate: b.reference for b in setup.biases if b.covariate is not None}
    cov = {c: np.asarray(covariates[i], dtype=float) - refs[c] for i, c in enumerate(setup.covariates)}
    yy = np.asarray(y, dtype=float)[None] - shift
    if group.prior_scale is None and not np.isfinite(yy).any():
        raise DataError("no valid sample in the first chunk to set the prior from; give prior_scale in the group")
    return drift_prior(setup, yy, cov, float(t[-1] - t[0]) if len(t) else 0.0, spread=group.prior_scale)


def filter_block(group: FleetGroup, y: np.ndarray, t: np.ndarray, states: Sequence[ChannelState | None],
                 covariates: np.ndarray | None = None, *, channels: Sequence[str] | None = None,
                 shared: bool | None = None, _model: _GroupModel | None = None
                 ) -> tuple[np.ndarray, np.ndarray, list[ChannelState]]:
    """Filter one chunk of many channels of one group (the pure core of a fleet run).

    Parameters
    ----------
    group : FleetGroup
    y : ndarray, (C, T)
        Measurements [unit], NaN = missing.
    t : ndarray, (T,)
        Time [s], strictly increasing, after every channel's ``t_last``.
    states : sequence of ChannelState or None
        Each channel's state before the chunk (None: not started; its prior
        is :func:`channel_prior` of this chunk).
    covariates : ndarray, (C, k, T), optional
        Each channel's covariates (``group.setup.covariates`` order), raw
        (the set-up's reference is subtracted here) [covariate unit].
    channels : sequence of str, optional
        Channel names (for per-channel levels and messages).
    shared : bool, optional
        Force (True) or forbid (False) the shared-covariance kernel; None:
        used whenever it gives the same numbers.

    Returns
    -------
    bias : ndarray, (C, T)
        Estimated bias [unit]; the corrected measurement is ``y - bias``.
    bias_std : ndarray, (C, T) or (T,)
        Its standard deviation (k=1) [unit]; one row when shared.
    states : list of ChannelState
    """
    gm = _model or _group_model(group)
    setup = group.setup
    y = np.ascontiguousarray(y, dtype=float)
    t = np.asarray(t, dtype=float).reshape(-1)
    C, T = y.shape
    if t.size != T:
        raise InputError(f"t has {t.size} samples but y has {T}")
    names = list(channels) if channels is not None else [str(i) for i in range(C)]
    kcov = len(setup.covariates)
    if kcov and (covariates is None or np.shape(covariates) != (C, kcov, T)):
        raise InputError(f"group {group.name} needs covariates {setup.covariates} of shape ({C}, {kcov}, {T})")
    if T == 0:
        return np.zeros((C, 0)), np.zeros((C, 0)), list(states)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise DataError("time stamps must be finite and strictly increasing")
    if np.isinf(y).any():
        raise DataError("measurements contain inf; use NaN for a missing sample")
    n = gm.h0.size
    started = np.array([s is not None for s in states], dtype=np.bool_)
    priors = []
    for c, s in enumerate(states):
        if s is not None:
            priors.append((s.x0, s.P0))
            continue
        try:
            priors.append(channel_prior(group, y[c], t, covariates[c] if kcov else None))
        except DataError as exc:
            raise DataError(f"channel {names[c]}: {exc}") from None
    x = np.array([s.x if s is not None else p[0] for s, p in zip(states, priors)], dtype=float).reshape(C, n)
    P = np.array([s.P if s is not None else p[1] for s, p in zip(states, priors)], dtype=float).reshape(C, n, n)
    t_last = np.array([s.t_last for s in states if s is not None], dtype=float)
    if t_last.size and not np.all(t_last == t_last[0]):
        # A block's channels share one time column, so they stop together.
        raise DataError("channels of one block were last updated at different times; run them separately")
    prev = t_last[0] if t_last.size else (t[0] - (t[1] - t[0]) if T > 1 else t[0] - 1.0)
    if not t[0] > prev:
        raise DataError(f"the chunk starts at t = {t[0]:.9g} s, not after the stored state's last sample "
                        f"t = {prev:.9g} s")
    dts = np.diff(np.concatenate([[prev], t]))
    F, Qu = gm.matrices(setup, dts)
    lev = [group.all_levels(c) for c in names]
    lev2 = np.array([[lv[p] ** 2 for p in gm.params] for lv in lev], dtype=float).reshape(C, len(gm.params))
    r2 = np.array([lv[f"{ROLE}_noise_std"] ** 2 for lv in lev])
    k = gm.cov_cols.size
    cov = np.zeros((C, k, T))
    if k:
        refs = {b.covariate: b.reference for b in setup.biases if b.covariate is not None}
        cols = [b.covariate for b in setup.biases if b.covariate is not None]
        src = {c: i for i, c in enumerate(setup.covariates)}
        for j, c in enumerate(cols):
            cov[:, j, :] = np.asarray(covariates, dtype=float)[:, src[c], :] - refs[c]
        bad = ~np.isfinite(cov).all(axis=(1, 2))
        if bad.any():
            raise DataError(f"a covariate of channel {names[int(np.argmax(bad))]} has NaN or inf; interpolate "
                            "its gaps first")
    bias = np.empty((C, T))
    can_share = (k == 0 and not np.isnan(y).any() and np.all(lev2 == lev2[:1]) and np.all(r2 == r2[0])
                 and np.all(started == started[0]) and np.all(P == P[:1]))
    if shared and not can_share:
        raise InputError("the channels of this block do not share their covariance (levels, covariates, "
                         "missing samples or prior differ)")
    if can_share if shared is None else shared:
        Ps = P[0].copy()
        Q = np.ascontiguousarray(np.einsum("p,ptij->tij", lev2[0], Qu))
        bvar = np.empty(T)
        if not _filter_shared(F, Q, float(r2[0]), gm.h0, y, gm.shift, x, Ps, bool(started[0]), gm.bias_mask,
                              bias, bvar):
            raise DataError(f"group {group.name}: the innovation variance is not positive; check the noise levels")
        P[:] = Ps
    else:
        bvar = np.empty((C, T))
        bad_c = _filter_channels(F, Qu, lev2, r2, gm.h0, gm.cov_cols, cov, y, gm.shift, x, P, started.copy(),
                                 gm.bias_mask, bias, bvar)
        if bad_c >= 0:
            raise DataError(f"channel {names[bad_c]}: the innovation variance is not positive; check its noise levels")
    std = np.sqrt(np.maximum(bvar, 0.0))
    new = [ChannelState(x=x[c].copy(), P=P[c].copy(), t_last=float(t[-1]),
                        n_samples=(s.n_samples if s is not None else 0) + T,
                        x0=np.asarray(priors[c][0], dtype=float), P0=np.asarray(priors[c][1], dtype=float))
           for c, s in enumerate(states)]
    return bias, std, new
