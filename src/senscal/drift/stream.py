"""Streaming drift correction: the augmented Kalman filter chunk by chunk, with a saved state.

A :class:`DriftTracker` runs the same augmented model
(:func:`~senscal.drift.model.augmented_model`) and the same Kalman kernels
as :func:`~senscal.drift.correct_drift`, but on data that arrive in pieces:
a file a day, a pipe, a Dask partition.  Its :class:`TrackerState` holds
everything needed to continue (the last filtered state, the fixed-lag
window of samples not yet final, the noise levels, the covariate
references), so that any chunking of a record -- one sample at a time,
chunks that split the lag window, one chunk per day across processes --
gives the one-pass output to rounding.

>>> tracker = DriftTracker(setup, levels, lag=60)            # doctest: +SKIP
>>> out = tracker.update(y_chunk, t_chunk, {"temperature": c})  # doctest: +SKIP
>>> tracker.state.save("drift-state.json")                   # doctest: +SKIP
>>> tracker = DriftTracker.from_state(TrackerState.load("drift-state.json"))  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from senscal._result import ResultMixin
from senscal.drift.core import channel_bias, drift_prior
from senscal.drift.model import Bias, DriftSetup, SignalModel, augmented_model
from senscal.errors import DataError, FileFormatError, InputError
from senscal.kalman import _kernels as K

__all__ = ["DriftTracker", "TrackerChunk", "TrackerState", "STATE_FORMAT_VERSION", "setup_to_dict",
           "setup_from_dict"]

#: Version of the saved state layout; a state of another version is refused.
STATE_FORMAT_VERSION = 1


# --------------------------------------------------------------------------- set-up (de)serialisation

def _plain(a: Any) -> Any:
    return None if a is None else np.asarray(a, dtype=float).tolist()


def setup_to_dict(setup: DriftSetup) -> dict[str, Any]:
    """The set-up as plain JSON types (exact: floats round-trip through ``repr``)."""
    sig = setup.signal
    return {
        "channels": list(setup.channels),
        "signal": {"kind": sig.kind, "level": sig.level, "tau": sig.tau, "mean": sig.mean,
                   "F": _plain(sig.F), "Q": _plain(sig.Q), "H": _plain(sig.H),
                   **({"tau_known": True} if sig.tau_known else {})},
        "biases": [{"channel": b.channel, "covariate": b.covariate, "reference": b.reference,
                    "dynamics": b.dynamics, "level": b.level, "tau": b.tau,
                    **({"lag": b.lag, "fit_lag": b.fit_lag} if (b.lag or b.fit_lag) else {})}
                   for b in setup.biases],
        "noise_std": {k: float(v) for k, v in setup.noise_std.items()},
        "trusted": list(setup.trusted),
        **({"ar_noise": list(setup.ar_noise)} if setup.ar_noise else {}),
    }


def setup_from_dict(doc: Mapping[str, Any]) -> DriftSetup:
    """Inverse of :func:`setup_to_dict`."""
    sig = dict(doc["signal"])
    return DriftSetup(channels=tuple(doc["channels"]), signal=SignalModel(**sig),
                      biases=tuple(Bias(**b) for b in doc["biases"]),
                      noise_std=dict(doc.get("noise_std") or {}), trusted=tuple(doc.get("trusted") or ()),
                      ar_noise=tuple(doc.get("ar_noise") or ()))


# --------------------------------------------------------------------------- results and state

@dataclass(frozen=True)
class TrackerChunk(ResultMixin):
    """The samples a :meth:`DriftTracker.update` made final.

    Attributes
    ----------
    t : ndarray, (k,)
        Time of the final samples [s] (with a lag, they trail the input by
        up to ``lag`` samples).
    channels : tuple of str
        Corrected channels (those with a bias), the rows below.
    corrected : ndarray, (mc, k)
        ``y - b_hat`` [unit].
    bias : ndarray, (mc, k)
        Total estimated bias of each corrected channel [unit].
    u_bias : ndarray, (mc, k)
        Its standard uncertainty (k=1) [unit].
    state, state_std : ndarray, (n, k)
        Augmented state ``[signal; biases]`` and its standard deviation
        (rows: ``DriftSetup.state_names``; the signal includes the known
        mean of a ``gauss_markov`` / ``known`` quantity).
    """

    t: np.ndarray
    channels: tuple[str, ...]
    corrected: np.ndarray
    bias: np.ndarray
    u_bias: np.ndarray
    state: np.ndarray
    state_std: np.ndarray

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)


# Per-sample arrays held while a sample is inside the fixed-lag window.
_BUFFER = ("t", "y", "h", "xf", "Pf", "xp", "Pp", "F")


@dataclass(frozen=True)
class TrackerState(ResultMixin):
    """Everything a :class:`DriftTracker` needs to continue, frozen.

    Attributes
    ----------
    setup : DriftSetup
    levels : dict of str to float
        Every noise level of ``setup.level_names()`` (standard deviations;
        random walks per sqrt(s)).
    lag : int
        Fixed-lag window [samples].
    references : dict of str to float
        Covariate value of zero covariate-linked bias, per covariate.
    x0, P0 : ndarray or None
        Prior of the first sample (None: taken from the first chunk).
    t_last : float or None
        Time of the last sample filtered [s] (None before any).
    x, P : ndarray or None
        Filtered state and covariance at ``t_last``.
    buffer : dict of str to ndarray
        Samples filtered but not yet final (at most ``lag``), time-major:
        ``t`` (k,), ``y`` (k, m), ``h`` (k, m, n) measurement matrices,
        ``xf``/``xp`` (k, n), ``Pf``/``Pp`` (k, n, n), ``F`` (k, n, n)
        transition into each sample.
    h_last : ndarray or None
        Measurement matrix (m, n) of the last sample (its covariate values);
        None in a state built by hand (``current`` then leaves
        covariate-linked terms unknown).
    n_samples : int
        Samples filtered so far.
    n_emitted : int
        Samples made final so far.
    loglik : float
        Log-likelihood of everything filtered so far [nats].
    """

    setup: DriftSetup
    levels: dict
    lag: int
    references: dict
    x0: np.ndarray | None
    P0: np.ndarray | None
    t_last: float | None
    x: np.ndarray | None
    P: np.ndarray | None
    buffer: dict
    h_last: np.ndarray | None = None
    n_samples: int = 0
    n_emitted: int = 0
    loglik: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types; NaN (a missing measurement) becomes null."""
        def arr(a):
            if a is None:
                return None
            a = np.asarray(a, dtype=float)
            return {"shape": list(a.shape),
                    "data": [None if not math.isfinite(v) else v for v in a.reshape(-1).tolist()]}

        return {
            "format_version": STATE_FORMAT_VERSION, "kind": "senscal drift tracker state",
            "setup": setup_to_dict(self.setup), "levels": {k: float(v) for k, v in self.levels.items()},
            "lag": int(self.lag), "references": {k: float(v) for k, v in self.references.items()},
            "x0": arr(self.x0), "P0": arr(self.P0), "t_last": self.t_last, "x": arr(self.x), "P": arr(self.P),
            "h_last": arr(self.h_last), "buffer": {k: arr(v) for k, v in self.buffer.items()},
            "n_samples": int(self.n_samples), "n_emitted": int(self.n_emitted), "loglik": float(self.loglik),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], *, source: str = "drift state") -> "TrackerState":
        """Rebuild a state from :meth:`to_dict`; a bad document raises a one-line FileFormatError."""
        if not isinstance(doc, Mapping):
            raise FileFormatError(f"{source} is not a drift tracker state (not a mapping)")
        if "type" in doc and "setup" not in doc:
            # A saved calibration (shaft model, triaxial parameters, ...) given where the state belongs.
            raise FileFormatError(f"{source} is a saved calibration (type {str(doc['type'])[:60]!r}), not a drift "
                                  "tracker state; give another --state file name (it is started on this data)")
        ver = doc.get("format_version")
        if ver != STATE_FORMAT_VERSION:
            raise FileFormatError(f"{source} has format_version {ver!r}; this senscal reads version "
                                  f"{STATE_FORMAT_VERSION} (start a new state, or use the senscal that wrote it)")

        def arr(v):
            if v is None:
                return None
            data = np.array([np.nan if x is None else x for x in v["data"]], dtype=float)
            return data.reshape(v["shape"])

        try:
            setup = setup_from_dict(doc["setup"])
            buffer = {k: arr(doc["buffer"][k]) for k in _BUFFER}
            state = cls(setup=setup, levels={k: float(v) for k, v in doc["levels"].items()}, lag=int(doc["lag"]),
                        references={k: float(v) for k, v in doc["references"].items()},
                        x0=arr(doc["x0"]), P0=arr(doc["P0"]),
                        t_last=None if doc["t_last"] is None else float(doc["t_last"]),
                        x=arr(doc["x"]), P=arr(doc["P"]), buffer=buffer, h_last=arr(doc["h_last"]), n_samples=int(doc["n_samples"]),
                        n_emitted=int(doc["n_emitted"]), loglik=float(doc["loglik"]))
        except InputError as exc:
            raise FileFormatError(f"{source} holds an invalid drift set-up ({exc})") from None
        except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
            # AttributeError: a mapping replaced by a list or a string in a hand-edited file.
            raise FileFormatError(f"{source} is not a valid drift tracker state ({type(exc).__name__}: "
                                  f"{str(exc)[:120]}); restore the previous state file or start a new one") from None
        _check_state(state, source)
        return state

    def save(self, path: str | Path) -> Path:
        """Write the state atomically (temporary file, then rename): JSON, or NPZ for a ``.npz`` path.

        A run killed while saving leaves the previous state file as it was.
        """
        from senscal.io.guard import atomic_output, check_output, protect_inputs

        # The state is read and then replaced by design (input and output of one
        # run): the folder and suffix checks apply, the never-overwrite-an-input
        # rule does not.
        with protect_inputs():
            path = check_output(path, suffixes=(".json", ".npz"), what="drift state")
        doc = self.to_dict()
        with atomic_output(path, what="drift state") as tmp:
            if path.suffix.lower() == ".npz":
                # Arrays stored as arrays (exact binary); the rest as one JSON string.
                arrays = {}
                for key in ("x0", "P0", "x", "P", "h_last"):
                    v = getattr(self, key)
                    if v is not None:
                        arrays[key] = np.asarray(v, dtype=float)
                        doc[key] = {"npz": key}
                for k, v in self.buffer.items():
                    arrays["buffer_" + k] = np.asarray(v, dtype=float)
                    doc["buffer"][k] = {"npz": "buffer_" + k}
                with open(tmp, "wb") as fh:
                    np.savez(fh, state_json=np.array(json.dumps(doc)), **arrays)
                    fh.flush()
            else:
                with open(tmp, "w", encoding="utf-8") as fh:
                    json.dump(doc, fh)
                    fh.flush()
        return path

    @classmethod
    def load(cls, path: str | Path) -> "TrackerState":
        """Read a state written by :meth:`save` (JSON or NPZ by suffix)."""
        from senscal.io.guard import note_input
        from senscal.io.sidefiles import read_json

        path = Path(path)
        what = f"drift state {path}"
        if path.suffix.lower() != ".npz":
            return cls.from_dict(read_json(path, "drift state"), source=what)
        note_input(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                doc = json.loads(str(z["state_json"]))
                stored = {k: np.array(z[k]) for k in z.files if k != "state_json"}
        except FileNotFoundError:
            raise FileFormatError(f"{what} does not exist") from None
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            # EOFError: an empty file; BadZipFile: a truncated one (a disk that filled up elsewhere).
            raise FileFormatError(f"{what} is not a drift state NPZ ({type(exc).__name__}); restore the previous "
                                  "state file or start a new one") from None

        def back(v):
            if isinstance(v, dict) and "npz" in v:
                a = stored.get(v["npz"])
                if a is None:
                    raise FileFormatError(f"{what} lacks array {v['npz']}")
                return {"shape": list(a.shape), "data": [None if not math.isfinite(x) else x
                                                         for x in a.reshape(-1).tolist()]}
            return v

        if isinstance(doc, dict):
            for key in ("x0", "P0", "x", "P", "h_last"):
                doc[key] = back(doc.get(key))
            if isinstance(doc.get("buffer"), dict):
                doc["buffer"] = {k: back(v) for k, v in doc["buffer"].items()}
        return cls.from_dict(doc, source=what)


#: Largest magnitude a restored number may have: the filter multiplies two of them (1e154**2 is still finite).
_MAX_ABS = 1e154


def _sane(a: np.ndarray) -> bool:
    return bool(np.all(np.abs(a) < _MAX_ABS))  # False for NaN and inf too


def _check_state(s: TrackerState, source: str) -> None:
    """Shapes and finiteness of a restored state (a hand-edited file must not crash the filter)."""
    n = len(s.setup.state_names)
    m = len(s.setup.channels)
    missing = [k for k in s.setup.level_names() if k not in s.levels]
    if missing:
        raise FileFormatError(f"{source} lacks noise levels {', '.join(missing)}")
    # A NaN or negative level, time or count would be filtered silently into wrong biases.
    bad = [k for k, v in s.levels.items() if not 0 <= v < math.inf]
    bad += [k for k, v in s.references.items() if not math.isfinite(v)]
    if s.t_last is not None and not math.isfinite(s.t_last):
        bad.append("t_last")
    bad += [k for k in ("n_samples", "n_emitted", "lag") if getattr(s, k) < 0]
    if bad:
        raise FileFormatError(f"{source}: {', '.join(bad[:5])} must be finite numbers >= 0 (a hand-edited or "
                              "damaged file?); restore the previous state file or start a new one")
    want = {"t": (None,), "y": (None, m), "h": (None, m, n), "xf": (None, n), "Pf": (None, n, n),
            "xp": (None, n), "Pp": (None, n, n), "F": (None, n, n)}
    k = None
    for key, shape in want.items():
        a = s.buffer[key]
        if a is None or a.ndim != len(shape) or tuple(a.shape[1:]) != shape[1:]:
            raise FileFormatError(f"{source}: buffer {key} has the wrong shape")
        k = a.shape[0] if k is None else k
        if a.shape[0] != k:
            raise FileFormatError(f"{source}: buffer arrays have different lengths")
        # Only a measurement may be missing (NaN); a NaN covariance would come out as a NaN uncertainty.
        if not (_sane(a[~np.isnan(a)]) if key == "y" else _sane(a)):
            raise FileFormatError(f"{source}: buffer {key} must hold finite numbers (a damaged file?); restore the "
                                  "previous state file or start a new one")
    for key, shape in (("x0", (n,)), ("P0", (n, n)), ("x", (n,)), ("P", (n, n)), ("h_last", (m, n))):
        a = getattr(s, key)
        if a is not None and (a.shape != shape or not _sane(a)):
            raise FileFormatError(f"{source}: {key} must be {shape} finite numbers below 1e154 (a damaged file?); "
                                  "restore the previous state file or start a new one")
    if (s.x is None) != (s.t_last is None) or (s.x is None and s.h_last is not None) or s.lag < 0 or k > max(s.lag, 0):
        raise FileFormatError(f"{source} is inconsistent (last state, time and window do not agree)")


def _h_unknown_covariates(s: TrackerState) -> np.ndarray:
    """Measurement matrix of a state built without its last sample's H: covariate columns unknown (NaN)."""
    setup = s.setup
    model = augmented_model(setup, np.ones(1), s.levels, {c: np.zeros(1) for c in setup.covariates})
    h = np.array(model._H[0])
    col = setup.signal.n_states
    for b in setup.biases:
        if b.covariate is not None:
            h[setup.channels.index(b.channel), col] = np.nan
        col += len(b.state_names)
    return h


# --------------------------------------------------------------------------- the tracker

class DriftTracker:
    """Augmented-state drift correction over data that arrive in chunks.

    Parameters
    ----------
    setup : DriftSetup
        What drifts (see :func:`~senscal.drift.redundant_setup` ...).
    levels : mapping of str to float
        Every noise level of ``setup.level_names()`` (e.g. the ``value`` of
        each :class:`~senscal.drift.NoiseParameter` of a
        :func:`~senscal.drift.correct_drift` run); levels fixed in the
        set-up win.
    lag : int
        Fixed-lag smoothing window [samples]: the estimate of a sample uses
        ``lag`` later samples, so it comes out ``lag`` samples late
        (0: the filter).
    prior : (x0, P0), optional
        Prior of the augmented state at the first sample; default: the rule
        of :func:`~senscal.drift.core.drift_prior` applied to the first chunk
        (give it, e.g. from a whole first file, when the first chunk is
        short: the output then does not depend on how the record is cut).
    references : mapping of str to float, optional
        Covariate value of zero covariate-linked bias; default the
        set-up's ``reference``, else the covariate's mean over the first
        chunk.
    """

    def __init__(self, setup: DriftSetup, levels: Mapping[str, float], *, lag: int = 0,
                 prior: tuple[Any, Any] | None = None, references: Mapping[str, float] | None = None) -> None:
        if not isinstance(setup, DriftSetup):
            raise InputError("setup must be a senscal.drift.DriftSetup")
        if int(lag) != lag or lag < 0:
            raise InputError(f"the lag must be a whole number of samples >= 0, got {lag}")
        lv = {k: float(v) for k, v in levels.items()}
        lv.update(setup.given_levels())
        missing = [k for k in setup.level_names() if k not in lv]
        if missing:
            raise InputError(f"noise levels {', '.join(missing)} are not given; estimate them first "
                             "(senscal.drift.correct_drift) or fix them in the set-up")
        for k, v in lv.items():
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"noise level {k} must be a finite number >= 0, got {v}")
        for c in setup.channels:
            if not lv[f"{c}_noise_std"] > 0:
                raise InputError(f"the noise std of {c} must be > 0")
        refs = {b.covariate: float(b.reference) for b in setup.biases
                if b.covariate is not None and b.reference is not None}
        for k, v in (references or {}).items():
            if k not in setup.covariates:
                raise InputError(f"a reference is given for {k}, which no bias of the set-up uses")
            if not math.isfinite(float(v)):
                raise InputError(f"the reference of {k} must be a finite number")
            refs[k] = float(v)
        x0 = P0 = None
        n = len(setup.state_names)
        if prior is not None:
            x0 = np.array(prior[0], dtype=float).reshape(-1)
            P0 = np.array(prior[1], dtype=float)
            if x0.shape != (n,) or P0.shape != (n, n) or not (np.isfinite(x0).all() and np.isfinite(P0).all()):
                raise InputError(f"prior must be (x0 of {n} numbers, P0 of shape ({n}, {n})), finite")
        empty = {"t": np.zeros(0), "y": np.zeros((0, len(setup.channels))),
                 "h": np.zeros((0, len(setup.channels), n)), "xf": np.zeros((0, n)), "Pf": np.zeros((0, n, n)),
                 "xp": np.zeros((0, n)), "Pp": np.zeros((0, n, n)), "F": np.zeros((0, n, n))}
        self._s = TrackerState(setup=setup, levels=lv, lag=int(lag), references=refs, x0=x0, P0=P0, t_last=None,
                               x=None, P=None, buffer=empty)

    # ---- state
    @classmethod
    def from_state(cls, state: TrackerState) -> "DriftTracker":
        """A tracker that continues exactly where ``state`` stopped."""
        if not isinstance(state, TrackerState):
            raise InputError("from_state needs a TrackerState")
        self = cls.__new__(cls)
        self._s = state
        return self

    @property
    def state(self) -> TrackerState:
        """The current state (frozen; save it to continue later)."""
        return self._s

    @property
    def setup(self) -> DriftSetup:
        return self._s.setup

    @property
    def levels(self) -> dict:
        return dict(self._s.levels)

    @property
    def lag(self) -> int:
        return self._s.lag

    @property
    def t_last(self) -> float | None:
        """Time of the last sample filtered [s]."""
        return self._s.t_last

    @property
    def channels(self) -> tuple[str, ...]:
        """The corrected channels (rows of the output)."""
        return tuple(self._s.setup.biased_channels)

    # ---- processing
    def _inputs(self, y_chunk: Any, t_chunk: Any, covariates: Mapping[str, Any] | None):
        setup = self._s.setup
        m = len(setup.channels)
        yy = np.array(y_chunk, dtype=float)
        if yy.ndim == 1 and m == 1:
            yy = yy[None]
        tt = np.asarray(t_chunk, dtype=float).reshape(-1)
        if yy.ndim != 2 or yy.shape[0] != m:
            raise InputError(f"y_chunk must have shape ({m}, n) for channels {', '.join(setup.channels)}, "
                             f"got {np.shape(y_chunk)}")
        if tt.size != yy.shape[1]:
            raise InputError(f"t_chunk has {tt.size} samples but y_chunk has {yy.shape[1]}")
        if not np.all(np.isfinite(tt)) or np.any(np.diff(tt) <= 0):
            raise DataError("time stamps must be finite and strictly increasing")
        if self._s.t_last is not None and tt.size and not tt[0] > self._s.t_last:
            raise DataError(f"the chunk starts at t = {tt[0]:.9g} s, not after the state's last sample "
                            f"t = {self._s.t_last:.9g} s: it does not continue the state")
        if np.any(np.isinf(yy)):
            raise DataError("measurements contain inf; use NaN for a missing sample")
        cov: dict[str, np.ndarray] = {}
        covariates = covariates or {}
        refs = dict(self._s.references)
        for name in setup.covariates:
            if name not in covariates:
                raise InputError(f"covariate {name} is needed by the set-up but was not given")
            c = np.asarray(covariates[name], dtype=float).reshape(-1)
            if c.size != tt.size or not np.all(np.isfinite(c)):
                raise DataError(f"covariate {name} must have {tt.size} finite samples (interpolate gaps first)")
            if name not in refs and c.size:
                refs[name] = float(np.mean(c))
            cov[name] = c - refs[name] if c.size else c
        return yy, tt, cov, refs

    def update(self, y_chunk: Any, t_chunk: Any, covariates: Mapping[str, Any] | None = None) -> TrackerChunk:
        """Filter a chunk and return the samples that became final.

        Parameters
        ----------
        y_chunk : array_like, (m, n)
            Measurements of ``setup.channels`` in that order [unit]; NaN =
            missing.
        t_chunk : array_like, (n,)
            Time [s], strictly increasing and after the last sample seen.
        covariates : mapping of str to array_like (n,), optional
            Covariate channels the set-up's biases name [covariate unit].

        Returns
        -------
        TrackerChunk
            With ``lag`` > 0, the samples whose window is complete: the last
            ``lag`` samples seen come out with the next chunk or
            :meth:`flush`.

        Notes
        -----
        ``self.innovations`` then holds the whitened innovations (m, n) of
        the chunk's samples (standard normal under the model; NaN where a
        measurement is missing) for model checks.
        """
        yy, tt, cov, refs = self._inputs(y_chunk, t_chunk, covariates)
        s = self._s
        self.innovations = np.zeros((len(s.setup.channels), 0))
        if tt.size == 0:
            return self._emit(0, s)
        setup = s.setup
        n = len(setup.state_names)
        shift = setup.signal.mean if setup.signal.kind in ("gauss_markov", "known") else 0.0
        yd = yy - shift
        x0, P0 = s.x0, s.P0
        if s.x is None and x0 is None:
            x0, P0 = drift_prior(setup, yd, cov, float(tt[-1] - tt[0]))
        if s.x is None:
            # First sample: the prior is its predicted state, as in a one-pass run.
            dt = np.empty(tt.size)
            dt[1:] = np.diff(tt)
            dt[0] = dt[1] if tt.size > 1 else 1.0
            y_in, cov_in, xs, Ps, skip = yd, cov, x0, P0, 0
        else:
            # Continue: a missing measurement at the last sample filtered, so that
            # the kernel's first prediction is the step from there into this chunk.
            dt = np.empty(tt.size + 1)
            dt[1:] = np.diff(np.concatenate([[s.t_last], tt]))
            dt[0] = dt[1]
            y_in = np.concatenate([np.full((yd.shape[0], 1), np.nan), yd], axis=1)
            cov_in = {k: np.concatenate([[0.0], v]) for k, v in cov.items()}
            xs, Ps, skip = s.x, s.P, 1
        model = augmented_model(setup, dt, s.levels, cov_in, x0=xs, P0=Ps)
        T = dt.size
        Y = np.ascontiguousarray(y_in.T)
        xf = np.empty((T, n))
        Pf = np.empty((T, n, n))
        xp = np.empty((T, n))
        Pp = np.empty((T, n, n))
        m = Y.shape[1]
        v = np.empty((T, m))
        Sc = np.empty((T, m, m))
        e = np.empty((T, m))
        rej = np.zeros(T, dtype=bool)
        # The steady-state shortcut is off: a chunk must end with the exact
        # covariance the next chunk starts from.
        ll, code = K.filter_series(model._F, model._B, model._H, model._Q, model._R, model.x0, model.P0, Y,
                                   np.zeros((T, 0)), 0.0, False, True, xf, Pf, xp, Pp, v, Sc, e, rej)
        if code == -2:
            raise DataError("the innovation covariance lost positive definiteness; check the noise levels "
                            "against the data's scale")
        # Whitened innovations of the new samples, for model checks by the caller (not part of the state).
        self.innovations = e[skip:].T.copy()
        Fst = np.broadcast_to(model._F, (T, n, n)) if model._F.shape[0] == 1 else model._F
        Hst = np.broadcast_to(model._H, (T, m, n)) if model._H.shape[0] == 1 else model._H
        new = {"t": tt, "y": yy.T, "h": Hst[skip:], "xf": xf[skip:], "Pf": Pf[skip:], "xp": xp[skip:],
               "Pp": Pp[skip:], "F": Fst[skip:]}
        buf = {k: np.concatenate([s.buffer[k], new[k]], axis=0) for k in _BUFFER}
        st = dataclasses.replace(s, references=refs, x0=x0, P0=P0, t_last=float(tt[-1]), x=xf[-1].copy(),
                                 P=Pf[-1].copy(), h_last=np.array(Hst[-1]), buffer=buf, n_samples=s.n_samples + tt.size,
                                 loglik=s.loglik + float(ll))
        return self._emit(max(buf["t"].size - st.lag, 0), st)

    def current(self) -> TrackerChunk:
        """The filtered estimate at the last sample seen (one sample; empty before any data).

        Not yet final with a lag (later data will smooth it), but it is what
        a monitoring display shows now, and at the end of a record it equals
        the one-pass estimate.
        """
        s = self._s
        if s.x is None:
            return self._emit_from(s, np.zeros(0), np.zeros((0, len(s.setup.channels))),
                                   np.zeros((0,) + (len(s.setup.channels), len(s.setup.state_names))),
                                   np.zeros((0, len(s.setup.state_names))),
                                   np.zeros((0, len(s.setup.state_names), len(s.setup.state_names))))
        y_last = s.buffer["y"][-1:] if s.buffer["t"].size else np.full((1, len(s.setup.channels)), np.nan)
        h = s.h_last if s.h_last is not None else _h_unknown_covariates(s)
        return self._emit_from(s, np.array([s.t_last]), y_last, h[None], s.x[None], s.P[None])

    def flush(self) -> TrackerChunk:
        """Emit the samples still in the lag window (end of data: shorter windows, as a one-pass run)."""
        return self._emit(self._s.buffer["t"].size, self._s)

    @staticmethod
    def _emit_from(st: TrackerState, t, y, h, x, P) -> TrackerChunk:
        """Bias, its u and corrected values of time-major estimates ``x`` (k, n), ``P`` (k, n, n)."""
        setup = st.setup
        k, n = x.shape
        chans = setup.biased_channels
        rows = [setup.channels.index(c) for c in chans]
        bias, bias_var = channel_bias(setup, h, x, P)
        corrected = y[:, rows].T - bias
        state = x.T.copy()
        if setup.signal.kind in ("gauss_markov", "known"):
            state[0] += setup.signal.mean
        std = np.sqrt(np.maximum(np.diagonal(P, axis1=1, axis2=2), 0.0)).T
        return TrackerChunk(t=np.asarray(t, dtype=float), channels=tuple(chans), corrected=corrected, bias=bias,
                            u_bias=np.sqrt(np.maximum(bias_var, 0.0)), state=state, state_std=std.reshape(n, k))

    def _emit(self, k: int, st: TrackerState) -> TrackerChunk:
        """Smooth and emit the first ``k`` buffered samples; keep the rest; commit ``st``."""
        buf = st.buffer
        if k and st.lag:
            C = K.smoother_gains(np.ascontiguousarray(buf["F"]), buf["Pf"], buf["Pp"])
            xs = np.empty_like(buf["xf"])
            Ps = np.empty_like(buf["Pf"])
            K.fixed_lag_series(C, buf["xf"], buf["Pf"], buf["xp"], buf["Pp"], st.lag, xs, Ps)
            x, P = xs[:k], Ps[:k]
        else:
            x, P = buf["xf"][:k], buf["Pf"][:k]
        out = self._emit_from(st, buf["t"][:k].copy(), buf["y"][:k], buf["h"][:k], x, P)
        if k:
            st = dataclasses.replace(st, buffer={key: buf[key][k:].copy() for key in _BUFFER},
                                     n_emitted=st.n_emitted + k)
        self._s = st
        return out
