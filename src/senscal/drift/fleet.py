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
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, ClassVar, Mapping, Sequence

import numba as nb
import numpy as np

from senscal.diagnostics import named
from senscal.drift.model import DriftSetup, augmented_model, covariate_setup, known_setup, load_model_yaml
from senscal.errors import DataError, FileFormatError, InputError
from senscal.jobs._base import JobResult
from senscal.kalman import _kernels as KK
from senscal.quantity import Quantity

__all__ = ["FleetGroup", "FleetBlock", "FleetOptions", "FleetResult", "ChannelState", "load_fleet_config",
           "channel_prior", "dataset_files", "open_store", "run_block", "fleet_groups", "plan_blocks", "run_fleet", "fleet", "read_store", "filter_block", "FORMAT_VERSION",
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
            raise InputError(f"fleet group {self.name}: prior_scale must be a number > 0 [unit], "
                             f"got {self.prior_scale}")
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
            # v * v: the filter works with variances, which must stay finite too (1e200 overflowed).
            if not (math.isfinite(v * v) and v >= 0) or (k.endswith("_noise_std") and not v > 0):
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
    if set(doc) != {"groups"}:
        # A misspelt key (``group:`` beside ``groups:``) would otherwise be ignored without a word.
        raise FileFormatError(f"fleet configuration {path} has unknown top-level keys "
                              f"{sorted(map(str, set(doc) - {'groups'}))[:5]}; it holds one list 'groups'")
    return fleet_groups(doc, base=path.parent, source=str(path))


def fleet_groups(doc: Mapping[str, Any], *, base: Path | str = ".", source: str = "fleet configuration"
                 ) -> tuple[FleetGroup, ...]:
    """Groups of a configuration document already read (see :func:`load_fleet_config`)."""
    base = Path(base)
    groups = []
    for i, g in enumerate(doc.get("groups") or []):
        if not isinstance(g, dict):
            raise FileFormatError(f"{source}: group {i} must be a mapping")
        bad = set(g) - {"name", "channels", "setup", "levels", "channel_levels", "covariate_column", "prior_scale"}
        if bad:
            raise FileFormatError(f"{source}: group {g.get('name', i)} has unknown keys {sorted(bad)}")
        name = g.get("name", f"group{i}")
        if not isinstance(name, str):
            raise FileFormatError(f"{source}: group {i}: name must be a text, got {type(name).__name__}")
        chans = g.get("channels", ["*"])
        chans = [chans] if isinstance(chans, str) else chans
        if not isinstance(chans, list) or not all(isinstance(c, str) for c in chans):
            raise FileFormatError(f"{source}: group {name}: channels must be a name or pattern, or a list of them "
                                  f"(texts), got {str(chans)[:60]}")
        per = g.get("channel_levels") or {}
        if isinstance(per, str):
            per = _read_channel_levels(base / per, name)
        if not isinstance(per, dict) or not all(isinstance(v, dict) for v in per.values()):
            raise FileFormatError(f"{source}: group {name}: channel_levels must be a CSV file name or a mapping "
                                  "channel -> {level: value}")
        if not isinstance(g.get("levels") or {}, dict):
            raise FileFormatError(f"{source}: group {name}: levels must be a mapping level -> value, e.g. "
                                  "{y_noise_std: 0.05}")
        try:
            groups.append(FleetGroup(name=name, setup=_setup_from(g.get("setup"), name, base),
                                     levels=dict(g.get("levels") or {}), channels=tuple(str(c) for c in chans),
                                     covariate_column=str(g.get("covariate_column", "{channel}.{covariate}")),
                                     channel_levels={str(k): dict(v) for k, v in per.items()},
                                     prior_scale=None if g.get("prior_scale") is None else float(g["prior_scale"])))
        except (TypeError, ValueError, OverflowError) as exc:
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


def _shared_classes(k: int, y: np.ndarray, lev2: np.ndarray, r2: np.ndarray, started: np.ndarray,
                    P: np.ndarray) -> list[np.ndarray]:
    """Channels that may share one Riccati recursion in this chunk, in classes of identical covariance.

    No covariate in ``H``, no missing sample in the chunk, and bit-identical
    levels, start flag and covariance: then their gains are equal for the
    whole chunk.  A channel that lost a sample goes through the per-channel
    kernel and rejoins a class once its covariance has converged back to the
    same bits.
    """
    if k:
        return []
    ok = ~np.isnan(y).any(axis=1)
    if ok.all() and (lev2 == lev2[:1]).all() and (r2 == r2[0]).all() and (started == started[0]).all() \
            and (P == P[:1]).all():
        return [np.arange(y.shape[0])]   # the usual case, without a key per channel
    classes: dict[bytes, list[int]] = {}
    for c in np.nonzero(ok)[0]:
        key = lev2[c].tobytes() + r2[c].tobytes() + bytes([bool(started[c])]) + P[c].tobytes()
        classes.setdefault(key, []).append(int(c))
    return [np.array(v) for v in classes.values() if len(v) > 1 or ok.sum() == y.shape[0]]


def _run_shared(group: FleetGroup, F: np.ndarray, Qu: np.ndarray, lev2: np.ndarray, r2: float, gm: _GroupModel,
                y: np.ndarray, x: np.ndarray, P: np.ndarray, started: bool, bias: np.ndarray, bvar: np.ndarray) -> None:
    """The shared-covariance kernel on channels of one class; updates x, P (all rows) in place."""
    Ps = P[0].copy()
    Q = np.ascontiguousarray(np.einsum("p,ptij->tij", lev2, Qu))
    if not _filter_shared(F, Q, float(r2), gm.h0, np.ascontiguousarray(y), gm.shift, x, Ps, started, gm.bias_mask,
                          bias, bvar):
        raise DataError(f"group {group.name}: the innovation variance is not positive; check the noise levels")
    P[:] = Ps


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
    if group.channel_levels:
        lev = [group.all_levels(c) for c in names]
    else:
        lev = [group.all_levels()]   # one set for every channel
    lev2 = np.array([[lv[p] ** 2 for p in gm.params] for lv in lev], dtype=float).reshape(len(lev), len(gm.params))
    r2 = np.array([lv[f"{ROLE}_noise_std"] ** 2 for lv in lev])
    lev2, r2 = np.ascontiguousarray(np.broadcast_to(lev2, (C, lev2.shape[1]))), np.broadcast_to(r2, (C,)).copy()
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
    classes = _shared_classes(k, y, lev2, r2, started, P) if shared is not False else []
    if shared and not (len(classes) == 1 and classes[0].size == C):
        raise InputError("the channels of this block do not share their covariance (levels, covariates, "
                         "missing samples or prior differ)")
    if len(classes) == 1 and classes[0].size == C:
        bvar = np.empty(T)
        _run_shared(group, F, Qu, lev2[0], r2[0], gm, y, x, P, bool(started[0]), bias, bvar)
    else:
        bvar = np.empty((C, T))
        rest = np.ones(C, dtype=bool)
        for idx in classes:
            rest[idx] = False
            xs, Ps, bs, vs = x[idx], P[idx], np.empty((idx.size, T)), np.empty(T)
            _run_shared(group, F, Qu, lev2[idx[0]], r2[idx[0]], gm, y[idx], xs, Ps, bool(started[idx[0]]), bs, vs)
            x[idx], P[idx], bias[idx], bvar[idx] = xs, Ps, bs, vs
        if rest.any():
            idx = np.nonzero(rest)[0]
            xs, Ps, bs, vs = x[idx], P[idx], np.empty((idx.size, T)), np.empty((idx.size, T))
            bad_c = _filter_channels(F, Qu, lev2[idx], r2[idx], gm.h0, gm.cov_cols, np.ascontiguousarray(cov[idx]),
                                     np.ascontiguousarray(y[idx]), gm.shift, xs, Ps, started[idx].copy(),
                                     gm.bias_mask, bs, vs)
            if bad_c >= 0:
                raise DataError(f"channel {names[idx[bad_c]]}: the innovation variance is not positive; check its "
                                "noise levels")
            x[idx], P[idx], bias[idx], bvar[idx] = xs, Ps, bs, vs
    std = np.sqrt(np.maximum(bvar, 0.0))
    new = [ChannelState(x=x[c].copy(), P=P[c].copy(), t_last=float(t[-1]),
                        n_samples=(s.n_samples if s is not None else 0) + T,
                        x0=np.asarray(priors[c][0], dtype=float), P0=np.asarray(priors[c][1], dtype=float))
           for c, s in enumerate(states)]
    return bias, std, new


# --------------------------------------------------------------------------- dataset, blocks, state store

@dataclass(frozen=True)
class FleetBlock:
    """The channels of one group in one dataset file: one task, its row groups in time order.

    Attributes
    ----------
    file : str
        Parquet file.
    group : str
        Group name.
    channels : tuple of str
        Channel columns.
    covariates : tuple of tuple of str
        Per channel, its covariate columns (the group set-up's order).
    """

    file: str
    group: str
    channels: tuple[str, ...]
    covariates: tuple[tuple[str, ...], ...]

    @property
    def key(self) -> str:
        """Name of the block's state file in the store (without ``.npz``)."""
        return f"{self.group}--{Path(self.file).stem}"


def dataset_files(dataset: str | Path) -> list[Path]:
    """The Parquet files of a fleet dataset: a file, or the ``*.parquet`` files of a folder, sorted."""
    from senscal.io.guard import note_input

    path = Path(dataset)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in (".parquet", ".pq") and p.is_file())
        if not files:
            raise InputError(f"fleet dataset {path} holds no .parquet files; give a folder of Parquet files "
                             "(one block of channels each, a time column t)")
    elif path.is_file():
        files = [path]
    else:
        raise InputError(f"fleet dataset {path} does not exist")
    for f in files:
        note_input(f)
    return files


def _check_column_types(f: Path) -> None:
    """Every column must hold plain numbers: a timestamp ``t`` read as nanoseconds would be taken for seconds."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    for fld in pq.read_schema(f):
        if not (pa.types.is_floating(fld.type) or pa.types.is_integer(fld.type)):
            fix = ("seconds as float64" if fld.name == "t" else "numbers (float64, NaN for a missing sample)")
            raise FileFormatError(f"fleet dataset file {f}: column {fld.name} has type {fld.type}; store {fix}")


def plan_blocks(dataset: str | Path, groups: Sequence[FleetGroup]) -> tuple[list[FleetBlock], list[str]]:
    """Assign every channel column of the dataset to the first group whose patterns match it.

    Returns
    -------
    blocks : list of FleetBlock
    warnings : list of str
        ``fleet-columns-unassigned``, ``fleet-group-empty``.
    """
    import pyarrow.parquet as pq

    blocks: list[FleetBlock] = []
    unassigned: list[str] = []
    used = {g.name: 0 for g in groups}
    seen: dict[str, str] = {}
    for f in dataset_files(dataset):
        try:
            names = pq.read_schema(f).names
        except (OSError, ValueError) as exc:
            raise FileFormatError(f"fleet dataset file {f} is not a readable Parquet file ({exc})") from None
        if "t" not in names:
            raise FileFormatError(f"fleet dataset file {f} has no time column t [s]")
        _check_column_types(f)
        cols = set(names)
        taken: dict[str, list[tuple[str, tuple[str, ...]]]] = {g.name: [] for g in groups}
        cov_cols = {c for g in groups for name in names for c in g.covariate_columns(name) if c in cols}
        for name in names:
            if name == "t" or name in cov_cols:
                continue
            g = next((g for g in groups if g.matches(name)), None)
            if g is None:
                unassigned.append(name)
                continue
            if name in seen:
                raise InputError(f"channel {name} is in both {seen[name]} and {f}; a channel must be in one file")
            seen[name] = str(f)
            want = g.covariate_columns(name)
            lack = [c for c in want if c not in cols]
            if lack:
                raise InputError(f"channel {name} of group {g.name} needs its covariate column {lack[0]} in {f} "
                                 f"(set covariate_column in the group, now {g.covariate_column!r})")
            taken[g.name].append((name, want))
        for g in groups:
            if taken[g.name]:
                used[g.name] += len(taken[g.name])
                blocks.append(FleetBlock(file=str(f), group=g.name, channels=tuple(c for c, _ in taken[g.name]),
                                         covariates=tuple(w for _, w in taken[g.name])))
    warnings = []
    if unassigned:
        warnings.append(named("fleet-columns-unassigned", (
            f"{len(unassigned)} columns match no group and were not processed ({', '.join(unassigned[:5])}"
            f"{', ...' if len(unassigned) > 5 else ''}); add a group or a pattern for them")))
    empty = [n for n, k in used.items() if k == 0]
    if empty:
        warnings.append(named("fleet-group-empty", f"groups {', '.join(empty)} match no column of the dataset; "
                              "check their channel patterns"))
    return blocks, warnings


def _group_doc(g: FleetGroup) -> dict[str, Any]:
    from senscal.drift.stream import setup_to_dict

    return {"setup": setup_to_dict(g.setup), "levels": dict(sorted(g.levels.items())),
            "channel_levels": {k: dict(sorted(v.items())) for k, v in sorted(g.channel_levels.items())},
            "prior_scale": g.prior_scale}


def open_store(store: str | Path, groups: Sequence[FleetGroup]) -> Path:
    """Create the state store folder, or check that its groups are the ones given.

    A store keeps, per group, the set-up and levels it was filtered with
    (``store.json``); continuing with other ones would mix two models in
    one state, so it is refused.
    """
    import json

    from senscal.io.guard import check_output_dir, write_text
    from senscal.io.sidefiles import read_json

    path = Path(store)
    man = path / "store.json"
    docs = {g.name: _group_doc(g) for g in groups}
    if man.exists():
        doc = read_json(man, "fleet state store")
        if doc.get("format_version") != FORMAT_VERSION:
            raise FileFormatError(f"fleet state store {path} has format_version {doc.get('format_version')!r}; "
                                  f"this senscal reads {FORMAT_VERSION}")
        old = doc.get("groups") or {}
        if not isinstance(old, dict):
            raise FileFormatError(f"fleet state store {man} is damaged ('groups' is not a mapping); restore it from "
                                  "a backup or start a new --state folder")
        for name, d in docs.items():
            if name in old and json.loads(json.dumps(old[name])) != json.loads(json.dumps(d)):
                raise InputError(f"group {name} of the state store {path} was filtered with another set-up, levels "
                                 "or prior; use a new --state folder (or give the group a new name)")
        docs = {**old, **docs}
    check_output_dir(path, what="fleet state store")
    write_text(man, json.dumps({"format_version": FORMAT_VERSION, "kind": "senscal drift fleet state",
                                "groups": docs}, indent=1) + "\n", what="fleet state store")
    return path


def _check_store_arrays(f: Path, a: Mapping[str, np.ndarray]) -> None:
    """Shapes and finiteness of one block's stored states: a damaged file must not skip rows or crash a worker."""
    C = a["channels"].shape[0] if a["channels"].ndim == 1 and a["channels"].dtype.kind == "U" else -1
    n = a["x"].shape[1] if a["x"].ndim == 2 else -1
    want = {"x": (C, n), "P": (C, n, n), "x0": (C, n), "P0": (C, n, n), "t_last": (C,), "n_samples": (C,),
            "bias": (C,), "u_bias": (C,)}
    bad = ["channels"] if C < 0 else ["x"] if n < 0 else [k for k, shape in want.items() if a[k].shape != shape]
    if not bad:
        bad = [k for k in ("x", "P", "x0", "P0", "t_last", "n_samples")
               if a[k].dtype.kind not in "fiu" or not np.all(np.isfinite(a[k]))]
    if not bad and np.any(a["n_samples"] < 0):
        bad = ["n_samples"]
    if bad:
        raise FileFormatError(f"fleet state file {f} is damaged ({', '.join(bad)} of the wrong shape or not finite); "
                              "restore it from a backup or start a new --state folder")


def read_store(store: str | Path) -> dict[str, tuple[str, ChannelState, float, float]]:
    """Every channel's latest state in a store.

    Returns
    -------
    dict
        channel -> (group, ChannelState, last bias [unit], its u [unit]).
    """
    path = Path(store)
    out: dict[str, tuple[str, ChannelState, float, float]] = {}
    if not path.is_dir():
        return out
    for f in sorted(path.glob("*.npz")):
        try:
            with np.load(f, allow_pickle=False) as z:
                if int(z["format_version"]) != FORMAT_VERSION:
                    raise FileFormatError(f"fleet state file {f} has format_version {int(z['format_version'])}; "
                                          f"this senscal reads {FORMAT_VERSION}")
                group = str(z["group"])
                arrs = {k: np.array(z[k]) for k in ("channels", "x", "P", "x0", "P0", "t_last", "n_samples",
                                                    "bias", "u_bias")}
        except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
            # EOFError: an empty file; BadZipFile: a truncated one; TypeError: a non-scalar version.
            raise FileFormatError(f"fleet state file {f} cannot be read ({type(exc).__name__}); restore it from "
                                  "a backup or start a new --state folder") from None
        _check_store_arrays(f, arrs)
        for i, c in enumerate(arrs["channels"].tolist()):
            st = ChannelState(x=arrs["x"][i], P=arrs["P"][i], t_last=float(arrs["t_last"][i]),
                              n_samples=int(arrs["n_samples"][i]), x0=arrs["x0"][i], P0=arrs["P0"][i])
            if c not in out or st.t_last > out[c][1].t_last:
                out[c] = (group, st, float(arrs["bias"][i]), float(arrs["u_bias"][i]))
    return out


def _save_block_state(store: Path, block: FleetBlock, states: Sequence[ChannelState], bias: np.ndarray,
                      u_bias: np.ndarray) -> None:
    """Write a block's states in one rename (a crash leaves the previous file whole)."""
    from senscal.io.guard import atomic_output

    with atomic_output(store / f"{block.key}.npz", what="fleet state file") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, format_version=np.array(FORMAT_VERSION), group=np.array(block.group),
                     channels=np.array(block.channels), x=np.array([s.x for s in states]),
                     P=np.array([s.P for s in states]), x0=np.array([s.x0 for s in states]),
                     P0=np.array([s.P0 for s in states]), t_last=np.array([s.t_last for s in states]),
                     n_samples=np.array([s.n_samples for s in states]), bias=bias, u_bias=u_bias)


def _write_chunk(out: Path, block: FleetBlock, index: int, t: np.ndarray, corrected: np.ndarray,
                 std: np.ndarray) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from senscal.io.guard import atomic_output

    folder = out / block.key
    folder.mkdir(parents=True, exist_ok=True)
    cols: dict[str, Any] = {"t": t}
    std = np.broadcast_to(std, corrected.shape)
    for i, c in enumerate(block.channels):
        cols[c] = corrected[i]
        cols[f"{c}.u_bias"] = std[i]
    # Named by the chunk's first time stamp, so a resumed run adds files and never clobbers.
    with atomic_output(folder / f"t{t[0]:017.3f}-{index:05d}.parquet", what="corrected chunk") as tmp:
        pq.write_table(pa.table(cols), tmp, compression="none")


def _read_chunk(pf, rg: int, block: FleetBlock, kcov: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    cols = ["t", *block.channels, *(c for cc in block.covariates for c in cc)]
    tbl = pf.read_row_group(rg, columns=cols)
    t = tbl.column(0).to_numpy(zero_copy_only=False).astype(float, copy=False)
    C = len(block.channels)
    y = np.empty((C, t.size))
    for i in range(C):
        y[i] = tbl.column(1 + i).to_numpy(zero_copy_only=False)
    cov = None
    if kcov:
        cov = np.empty((C, kcov, t.size))
        for i in range(C):
            for j in range(kcov):
                cov[i, j] = tbl.column(1 + C + i * kcov + j).to_numpy(zero_copy_only=False)
    return t, y, cov


def run_block(block: FleetBlock, group: FleetGroup, states: Mapping[str, ChannelState | None],
              store: str | None, out: str | None) -> dict[str, Any]:
    """Filter one block: its row groups in time order, saving the state after each.

    Runs in a Dask worker (or in this process).  Rows at or before the
    block's stored time are skipped: a resumed run continues after the last
    row group whose state was saved.

    Returns
    -------
    dict
        ``channels``, ``bias`` / ``u_bias`` (last sample, [unit]),
        ``t_last`` [s], ``n_samples`` and ``n_missing`` (this run),
        ``n_skipped`` (rows already in the state), ``shared`` (row groups
        done by the shared kernel), ``chunks``, ``seconds``.
    """
    import pyarrow.parquet as pq

    t0 = time.perf_counter()
    gm = _group_model(group)
    st = [states.get(c) for c in block.channels]
    C = len(block.channels)
    bias_last = np.full(C, np.nan)
    u_last = np.full(C, np.nan)
    n_new = n_missing = n_skip = chunks = shared = 0
    n_valid = np.zeros(C, dtype=np.int64)
    kcov = len(group.setup.covariates)
    try:
        pf = pq.ParquetFile(block.file)
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"fleet dataset file {block.file} cannot be read ({exc})") from None
    storep = Path(store) if store else None
    outp = Path(out) if out else None
    for rg in range(pf.metadata.num_row_groups):
        try:
            t, y, cov = _read_chunk(pf, rg, block, kcov)
        except (OSError, ValueError) as exc:  # pyarrow: a damaged page (ArrowInvalid is a ValueError)
            why = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else type(exc).__name__
            raise FileFormatError(f"fleet dataset file {block.file}, row group {rg} cannot be read ({why}); "
                                  "replace the file with a good copy") from None
        if t.size == 0:
            continue
        if not np.all(np.isfinite(t)):
            raise DataError(f"{block.file}, row group {rg}: time stamps must be finite and strictly increasing "
                            f"(t has NaN or inf in data row {int(np.argmin(np.isfinite(t))) + 1})")
        # Channels continue from where each stopped: those with the same last time run together
        # (a channel new in this file starts from its prior beside the others).
        parts: dict[float, list[int]] = {}
        for i, s_ in enumerate(st):
            parts.setdefault(s_.t_last if s_ is not None else -math.inf, []).append(i)
        rows = np.zeros(t.size, dtype=bool)
        bias = std = None
        if len(parts) > 1 or any(k >= t[0] for k in parts):
            bias = np.full((C, t.size), np.nan)
            std = np.full((C, t.size), np.nan)
        one = None
        for t_done, idx in parts.items():
            keep = t > t_done
            n_skip += int((~keep).sum()) * len(idx)
            if not keep.any():
                continue
            ix = np.array(idx)
            whole = len(idx) == C and keep.all()
            # The usual case (every channel, every row) passes the chunk itself: no copies.
            yk = y if whole else y[np.ix_(ix, np.nonzero(keep)[0])]
            ck = cov if whole or cov is None else cov[ix][:, :, keep]
            try:
                b, u, new = filter_block(group, yk, t[keep], [st[i] for i in idx], ck,
                                         channels=[block.channels[i] for i in idx], _model=gm)
            except (DataError, InputError) as exc:
                raise type(exc)(f"{block.file}, row group {rg}: {exc}") from None
            for k, i in enumerate(idx):
                st[i] = new[k]
            if whole:
                bias, std = b, u
            else:
                bias[np.ix_(ix, np.nonzero(keep)[0])] = b
                std[np.ix_(ix, np.nonzero(keep)[0])] = np.broadcast_to(u, b.shape)
            bias_last[ix], u_last[ix] = b[:, -1], np.broadcast_to(u, b.shape)[:, -1]
            rows |= keep
            one = u if len(parts) == 1 else None
            n_new += b.size
            n_missing += int(np.count_nonzero(np.isnan(yk)))
            n_valid[ix] += np.count_nonzero(~np.isnan(yk), axis=1)
        if not rows.any():
            continue
        shared += one is not None and one.ndim == 1
        if outp is not None:
            _write_chunk(outp, block, rg, t[rows], (y - bias)[:, rows], std[..., rows])
        if storep is not None:
            _save_block_state(storep, block, st, bias_last, u_last)
        chunks += 1
    return {"channels": block.channels, "group": block.group, "bias": bias_last, "u_bias": u_last,
            "t_last": np.array([s.t_last if s is not None else np.nan for s in st]),
            "n_samples": n_new, "n_missing": n_missing, "n_skipped": n_skip, "chunks": chunks, "shared": shared,
            "n_valid": n_valid, "seconds": time.perf_counter() - t0}


# --------------------------------------------------------------------------- the run

@dataclass(frozen=True)
class FleetOptions:
    """Options of a fleet run.

    Attributes
    ----------
    config : path or tuple of FleetGroup
        The groups (a configuration file, see :func:`load_fleet_config`).
    state : path, optional
        State store folder: loaded if it exists, updated after every row
        group of every block.  None: start from the priors, keep nothing.
    out : path, optional
        Folder for the corrected data: per block a folder of Parquet files,
        one per row group, with ``t``, ``<channel>`` (corrected) and
        ``<channel>.u_bias`` [unit].
    workers : int
        Worker processes of the local Dask cluster (0: every block in this
        process, one after another).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); overrides
        ``workers``.
    """

    config: Any = None
    state: str | None = None
    out: str | None = None
    workers: int = 2
    scheduler: str | None = None


@dataclass(frozen=True)
class FleetResult(JobResult):
    """What a fleet run did, per channel.

    Attributes
    ----------
    dataset : str
    state, out : str or None
    channels : tuple of str
    groups : tuple of str
        Each channel's group.
    bias, u_bias : ndarray, (C,)
        Estimated bias at each channel's last sample and its standard
        uncertainty (k=1) [unit].
    t_last : ndarray, (C,)
        Time of each channel's last sample filtered [s].
    n_samples : int
        Samples filtered in this run (all channels).
    n_missing : int
        Of which missing (NaN).
    n_skipped : int
        Samples at or before the stored state, skipped.
    n_blocks : int
        Tasks (one per file and group).
    shared_chunks, chunks : int
        Row groups filtered, and of them by the shared-covariance kernel.
    workers : int
        Dask workers (0: in this process).
    wall_seconds : float
        Wall time of the filtering [s].
    warnings : tuple of str
    """

    job: ClassVar[str] = "drift-fleet"
    dataset: str
    state: str | None
    out: str | None
    channels: tuple[str, ...]
    groups: tuple[str, ...]
    bias: np.ndarray
    u_bias: np.ndarray
    t_last: np.ndarray
    n_samples: int
    n_missing: int
    n_skipped: int
    n_blocks: int
    chunks: int
    shared_chunks: int
    workers: int
    wall_seconds: float
    warnings: tuple[str, ...] = ()

    @property
    def samples_per_second(self) -> float:
        """Throughput of the run [samples/s] (reading, filtering, saving state)."""
        return self.n_samples / self.wall_seconds if self.wall_seconds > 0 else float("nan")

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``senscal drift-fleet --json``."""
        def num(v):
            v = float(v)
            return v if math.isfinite(v) else None

        return {
            "dataset": self.dataset, "state": self.state, "out": self.out, "n_channels": len(self.channels),
            "n_samples": int(self.n_samples), "n_missing": int(self.n_missing), "n_skipped": int(self.n_skipped),
            "n_blocks": int(self.n_blocks), "chunks": int(self.chunks), "shared_chunks": int(self.shared_chunks),
            "workers": int(self.workers), "wall_seconds": float(self.wall_seconds),
            "samples_per_second": num(self.samples_per_second),
            "channels": {c: {"group": g, "bias": num(b), "u_bias": num(u), "t_last": num(tl)}
                         for c, g, b, u, tl in zip(self.channels, self.groups, self.bias, self.u_bias, self.t_last)},
            "warnings": list(self.warnings),
        }

    def quantities(self) -> tuple[Quantity, ...]:
        """``<channel>.bias`` at its last sample, for every channel with one."""
        return tuple(Quantity(f"{c}.bias", float(b), float(u), "", 2.0)
                     for c, b, u in zip(self.channels, self.bias, self.u_bias) if math.isfinite(b) and math.isfinite(u))

    def to_dataframe(self):
        """One row per channel: channel, group, bias, u_bias, t_last."""
        import pandas as pd

        return pd.DataFrame({"channel": list(self.channels), "group": list(self.groups), "bias": self.bias,
                             "u_bias": self.u_bias, "t_last": self.t_last})


class _Client:
    """A Dask client for the run: an existing scheduler, a local cluster, or none (this process)."""

    def __init__(self, workers: int, scheduler: str | None) -> None:
        if int(workers) != workers or workers < 0:
            raise InputError(f"workers must be a whole number >= 0, got {workers}")
        self.workers, self.scheduler = int(workers), scheduler
        self.client = self.cluster = None

    def __enter__(self):
        if not self.scheduler and self.workers == 0:
            return None
        from dask.distributed import Client, LocalCluster

        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout="10s")
            except (OSError, ValueError, TypeError) as exc:  # TimeoutError is an OSError
                raise InputError(f"cannot connect to the Dask scheduler {self.scheduler!r} ({type(exc).__name__}: "
                                 f"{' '.join(str(exc).split())[:150]}); give an address like tcp://host:8786") from None
        else:
            # One thread per worker: the kernels hold the GIL-free cores themselves.
            self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, dashboard_address=":0",
                                        silence_logs=50)
            self.client = Client(self.cluster)
        return self.client

    def __exit__(self, *exc):
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        return False


def _outside_dataset(dataset: str | Path, **folders: str | Path | None) -> None:
    """Refuse a state or output folder inside the dataset: it would change the input (and the next run's files)."""
    data = Path(dataset).resolve()
    if not data.is_dir():
        return
    for opt, folder in folders.items():
        if folder is not None:
            f = Path(folder).resolve()
            if f == data or data in f.parents:
                raise InputError(f"--{opt} {folder} is inside the dataset {dataset}, which is an input; give a "
                                 "folder outside it")


def run_fleet(dataset: str | Path, groups: Sequence[FleetGroup], *, state: str | Path | None = None,
              out: str | Path | None = None, client: Any = None,
              progress: Callable[[dict], None] | None = None) -> FleetResult:
    """Filter every channel of a fleet dataset, blocks in parallel, row groups in time order.

    Parameters
    ----------
    dataset : path
        Folder of Parquet files (or one file): a time column ``t`` [s] and
        channel columns, cut into row groups.
    groups : sequence of FleetGroup
    state : path, optional
        State store folder (see :class:`FleetOptions`).
    out : path, optional
        Folder for the corrected data.
    client : dask.distributed.Client, optional
        Run the blocks on it; None: in this process.
    progress : callable, optional
        Called with each block's summary as it finishes.

    Returns
    -------
    FleetResult
    """
    from senscal.io.guard import check_output_dir

    groups = tuple(groups)
    if not groups:
        raise InputError("a fleet run needs at least one channel group")
    by_name = {g.name: g for g in groups}
    blocks, warnings = plan_blocks(dataset, groups)
    _outside_dataset(dataset, state=state, out=out)
    stored = {}
    if state is not None:
        open_store(state, groups)
        stored = read_store(state)
        moved = [c for b in blocks for c in b.channels if c in stored and stored[c][0] != b.group]
        if moved:
            raise InputError(f"channel {moved[0]} was filtered in group {stored[moved[0]][0]} before; a channel "
                             "cannot change group within one state store (use a new --state folder)")
    if out is not None:
        check_output_dir(out, what="corrected data folder")
    store_s = str(state) if state is not None else None
    out_s = str(out) if out is not None else None
    t0 = time.perf_counter()
    rows = []
    args = [(b, by_name[b.group], {c: stored[c][1] for c in b.channels if c in stored}, store_s, out_s)
            for b in blocks]
    if client is None:
        for a in args:
            rows.append(run_block(*a))
            if progress:
                progress(rows[-1])
        workers = 0
    else:
        from dask.distributed import as_completed

        workers = len(client.scheduler_info().get("workers", {}))
        futs = [client.submit(run_block, *a, key=f"fleet-{a[0].key}-{i}", pure=False) for i, a in enumerate(args)]
        for fut in as_completed(futs):
            rows.append(fut.result())
            if progress:
                progress(rows[-1])
    wall = time.perf_counter() - t0
    rows.sort(key=lambda r: [b.channels for b in blocks].index(r["channels"]))
    chans = [c for r in rows for c in r["channels"]]
    bias = np.concatenate([r["bias"] for r in rows]) if rows else np.zeros(0)
    u = np.concatenate([r["u_bias"] for r in rows]) if rows else np.zeros(0)
    for i, c in enumerate(chans):
        if not math.isfinite(bias[i]) and c in stored:
            # Nothing new for this channel: its last estimate is the stored one.
            bias[i], u[i] = stored[c][2], stored[c][3]
    # A channel never measured (every sample NaN, no stored estimate) reports its prior, not a measurement.
    blind = [c for r in rows for c, k in zip(r["channels"], r["n_valid"]) if k == 0 and c not in stored]
    if blind:
        warnings.append(named("fleet-channel-no-data", (
            f"{len(blind)} channels have no valid sample ({', '.join(blind[:5])}{', ...' if len(blind) > 5 else ''}): "
            "their bias and u are the prior, not a measurement; check the sensors or leave them out")))
    n_skip = sum(r["n_skipped"] for r in rows)
    if n_skip:
        warnings.append(named("fleet-rows-skipped", (
            f"{n_skip} samples at or before the stored state's last time were skipped (already filtered: a "
            "resumed run, or a file given twice)")))
    return FleetResult(dataset=str(dataset), state=store_s, out=out_s, channels=tuple(chans),
                       groups=tuple(r["group"] for r in rows for _ in r["channels"]), bias=bias, u_bias=u,
                       t_last=np.concatenate([r["t_last"] for r in rows]) if rows else np.zeros(0),
                       n_samples=sum(r["n_samples"] for r in rows),
                       n_missing=sum(r["n_missing"] for r in rows), n_skipped=n_skip, n_blocks=len(blocks),
                       chunks=sum(r["chunks"] for r in rows), shared_chunks=sum(r["shared"] for r in rows),
                       workers=workers, wall_seconds=wall, warnings=tuple(warnings))


def fleet(source: str | Path, options: FleetOptions | None = None) -> FleetResult:
    """The ``drift-fleet`` job: :func:`run_fleet` with its options (a local cluster by default).

    Parameters
    ----------
    source : path
        The fleet dataset (folder of Parquet files).
    options : FleetOptions

    Returns
    -------
    FleetResult
    """
    opts = options or FleetOptions()
    if opts.config is None:
        raise InputError("a fleet run needs a configuration of channel groups (--config FLEET.yaml)")
    groups = (load_fleet_config(opts.config) if isinstance(opts.config, (str, os.PathLike))
              else tuple(opts.config))
    with _Client(opts.workers, opts.scheduler) as client:
        return run_fleet(source, groups, state=opts.state, out=opts.out, client=client)
