"""The linear Gaussian state-space model."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError

__all__ = ["StateSpaceModel", "DEFAULT_P0_SCALE"]

#: Diagonal of the default initial covariance (a vague prior, in the state's
#: units squared): large enough that the first measurements dominate.
DEFAULT_P0_SCALE = 1e6


def _matrix(name: str, A: Any, rows: int | None, cols: int | None) -> np.ndarray:
    """Validate a constant (r, c) or per-step (T, r, c) matrix; return (1|T, r, c)."""
    try:
        a = np.array(A, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric matrix") from None
    if a.ndim == 0 and rows in (None, 1) and cols in (None, 1):
        a = a.reshape(1, 1)
    if a.ndim == 1 and rows in (None, 1) and cols is not None and a.size == cols:
        a = a.reshape(1, -1)
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3:
        raise InputError(f"{name} must be a matrix of shape (rows, cols) or (T, rows, cols), got shape {np.shape(A)}")
    if (rows is not None and a.shape[1] != rows) or (cols is not None and a.shape[2] != cols):
        want = f"({rows if rows is not None else 'r'}, {cols if cols is not None else 'c'})"
        raise InputError(f"{name} must have shape {want} (or (T, ...) per step), got {a.shape[1:]}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} contains NaN or inf; give finite values")
    return np.ascontiguousarray(a)


def _check_cov(name: str, A: np.ndarray, *, definite: bool) -> None:
    """Symmetric and positive (semi)definite, with a tolerance relative to scale."""
    scale = max(float(np.max(np.abs(A))), np.finfo(float).tiny)
    if not np.allclose(A, np.swapaxes(A, -1, -2), rtol=1e-10, atol=1e-12 * scale):
        raise InputError(f"{name} must be symmetric; use (A + A.T)/2 if it is only off by rounding")
    w = np.linalg.eigvalsh(0.5 * (A + np.swapaxes(A, -1, -2)))
    lo = float(w.min())
    if definite and lo <= 0.0:
        raise InputError(f"{name} must be positive definite (smallest eigenvalue {lo:.3g}); a measurement noise covariance needs every variance > 0")
    if lo < -1e-10 * scale:
        raise InputError(f"{name} must be positive semidefinite (smallest eigenvalue {lo:.3g})")


@dataclass(frozen=True)
class StateSpaceModel(ResultMixin):
    """Linear Gaussian state-space model.

    ``x_t = F_t x_{t-1} + B_t u_{t-1} + w_t``,  ``w_t ~ N(0, Q_t)``;
    ``y_t = H_t x_t + v_t``,  ``v_t ~ N(0, R_t)``;  ``x_0 ~ N(x0, P0)``.

    ``Q`` is the process noise and ``R`` the measurement noise covariance
    (the patent seed names them the other way round).  Every matrix is either
    constant or given per step with a leading time axis of length T; for the
    per-step transition quantities (F, B, Q) index ``t`` is the step *into*
    sample ``t``, so their entry 0 is never used.

    Parameters
    ----------
    F : array_like, (n, n) or (T, n, n)
        State transition matrix [state units / state units].
    H : array_like, (m, n) or (T, m, n)
        Measurement matrix [measurement units / state units].
    Q : array_like, (n, n) or (T, n, n)
        Process noise covariance [state units^2], symmetric PSD.
    R : array_like, (m, m) or (T, m, m)
        Measurement noise covariance [measurement units^2], symmetric PD.
    B : array_like, (n, k) or (T, n, k), optional
        Control input matrix [state units / control units].
    x0 : array_like, (n,), optional
        Prior mean of the state at the first sample; default zeros.
    P0 : array_like, (n, n), optional
        Prior covariance of the state at the first sample; default
        ``DEFAULT_P0_SCALE * I`` (vague).

    Raises
    ------
    InputError
        Inconsistent shapes, non-finite entries, non-symmetric or
        non-PSD covariances (one-line message).

    References
    ----------
    R. E. Kalman, "A new approach to linear filtering and prediction
    problems", J. Basic Eng. 82 (1960) 35-45.
    """

    F: np.ndarray
    H: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    B: np.ndarray | None = None
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    # Validated (1|T, r, c) stacks used by the kernels.
    _F: np.ndarray = field(init=False, repr=False, compare=False)
    _H: np.ndarray = field(init=False, repr=False, compare=False)
    _Q: np.ndarray = field(init=False, repr=False, compare=False)
    _R: np.ndarray = field(init=False, repr=False, compare=False)
    _B: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._validate(check_q=True)

    @classmethod
    def _built(cls, F: Any, H: Any, Q: Any, R: Any, *, x0: Any = None, P0: Any = None) -> "StateSpaceModel":
        """A model whose ``Q`` the caller built symmetric positive semidefinite by construction.

        For code that assembles ``Q`` from discretised noise blocks (e.g. the
        drift model: non-negative levels squared times blocks that are PSD for
        any step > 0) and builds the model many times.  Shapes, finiteness,
        ``R`` and ``P0`` are checked as by the constructor; of ``Q`` only its
        diagonal (>= 0: catches a negative step).  The symmetry and eigenvalue
        tests of a per-step ``(T, n, n)`` stack cost more than the filter pass
        they guard (40-70 ms against 30-120 ms at 65,000 steps; issue 30).
        """
        obj = cls.__new__(cls)
        for name, value in (("F", F), ("H", H), ("Q", Q), ("R", R), ("B", None), ("x0", x0), ("P0", P0)):
            object.__setattr__(obj, name, value)
        obj._validate(check_q=False)
        return obj

    def _validate(self, *, check_q: bool) -> None:
        F = np.asarray(self.F, dtype=float)
        if F.ndim == 0:
            F = F.reshape(1, 1)
        if F.ndim not in (2, 3) or F.shape[-1] != F.shape[-2]:
            raise InputError(f"F must be square, shape (n, n) or (T, n, n), got {np.shape(self.F)}")
        n = F.shape[-1]
        _F = _matrix("F", F, n, n)
        _H = _matrix("H", self.H, None, n)
        m = _H.shape[1]
        _Q = _matrix("Q", self.Q, n, n)
        _R = _matrix("R", self.R, m, m)
        if check_q:
            _check_cov("Q", _Q, definite=False)
        elif np.any(np.diagonal(_Q, axis1=1, axis2=2) < 0.0):
            raise InputError("Q must be positive semidefinite (a negative variance on its diagonal)")
        _check_cov("R", _R, definite=True)
        _B = np.zeros((1, n, 0)) if self.B is None else _matrix("B", self.B, n, None)
        x0 = np.zeros(n) if self.x0 is None else np.array(self.x0, dtype=float).reshape(-1)
        if x0.shape != (n,) or not np.all(np.isfinite(x0)):
            raise InputError(f"x0 must be {n} finite numbers (one per state), got shape {np.shape(self.x0)}")
        P0 = DEFAULT_P0_SCALE * np.eye(n) if self.P0 is None else np.array(self.P0, dtype=float)
        if P0.shape != (n, n) or not np.all(np.isfinite(P0)):
            raise InputError(f"P0 must be a finite ({n}, {n}) matrix, got shape {np.shape(self.P0)}")
        _check_cov("P0", P0[None], definite=False)
        lengths = {a.shape[0] for a in (_F, _H, _Q, _R, _B) if a.shape[0] > 1}
        if len(lengths) > 1:
            raise InputError(f"per-step matrices have different lengths {sorted(lengths)}; give them all for the same T")
        set_ = object.__setattr__
        set_(self, "F", _F[0] if _F.shape[0] == 1 else _F)
        set_(self, "H", _H[0] if _H.shape[0] == 1 else _H)
        set_(self, "Q", _Q[0] if _Q.shape[0] == 1 else _Q)
        set_(self, "R", _R[0] if _R.shape[0] == 1 else _R)
        if self.B is not None:
            set_(self, "B", _B[0] if _B.shape[0] == 1 else _B)
        set_(self, "x0", np.ascontiguousarray(x0))
        set_(self, "P0", np.ascontiguousarray(0.5 * (P0 + P0.T)))
        for name, a in (("_F", _F), ("_H", _H), ("_Q", _Q), ("_R", _R), ("_B", _B)):
            set_(self, name, a)

    @property
    def n_states(self) -> int:
        """Number of states n."""
        return self._F.shape[1]

    @property
    def n_measurements(self) -> int:
        """Number of measurement components m."""
        return self._H.shape[1]

    @property
    def n_inputs(self) -> int:
        """Number of control inputs k (0 without B)."""
        return self._B.shape[2]

    @property
    def time_varying(self) -> bool:
        """True when any matrix is given per step."""
        return any(a.shape[0] > 1 for a in (self._F, self._H, self._Q, self._R, self._B))

    @property
    def n_steps(self) -> int | None:
        """T of the per-step matrices, or None for a time-invariant model."""
        lengths = [a.shape[0] for a in (self._F, self._H, self._Q, self._R, self._B) if a.shape[0] > 1]
        return lengths[0] if lengths else None

    def replace(self, **changes: Any) -> "StateSpaceModel":
        """A copy with some matrices replaced (validated again)."""
        kw = {k: getattr(self, k) for k in ("F", "H", "Q", "R", "B", "x0", "P0")}
        kw.update(changes)
        return StateSpaceModel(**kw)
