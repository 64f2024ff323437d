"""Model choice by the data's own evidence: held-out error over contiguous time blocks.

Every candidate model is fitted on four of five contiguous blocks of the
recording and its calibration is applied to the fifth, as ``triaxial apply``
would apply it to new data; the held-out error of a reading is its
corrected field norm relative to the field the calibration promises
(:func:`held_out_norm_error`, dimensionless: ``|H| / F - 1``).  That is
what a user sees after ``apply``, and it puts models with different numbers
of parameters on one scale.  (The maximum-likelihood magnitude residual in
raw sensor units, used before, weighs readings by the fitted model's own
gains: a model that shrank an axis looked better than it corrects.)  On a
turn about one axis, where the planar model is a candidate, every model is
scored on the norm of the two in-plane axes instead: that is what the turn
determines (and what a heading uses), and the 3-D norm of a full model
would dilute its in-plane error by the constant out-of-plane field.
Contiguous blocks (not random samples) make a model that only interpolates
between neighbouring, correlated readings pay for it: each block is a part
of the motion the fit has not seen.

The simplest candidate whose held-out error is not significantly larger
than the best one's is chosen.  "Significantly" is a paired test on the
per-reading squared residuals (``z = mean(d) / (sd(d) / sqrt(n))``,
``d = r_candidate^2 - r_best^2``) at z = 2, the project's k=2: a simpler
model is preferred only while the data cannot tell it from the best.

References
----------
.. [1] M. Stone, "Cross-validatory choice and assessment of statistical
   predictions", J. R. Stat. Soc. B 36 (1974) 111-147.
.. [2] D. R. Roberts et al., "Cross-validation strategies for data with
   temporal, spatial, hierarchical, or phylogenetic structure", Ecography 40
   (2017) 913-929 (blocked cross-validation).
.. [3] F. X. Diebold, R. S. Mariano, "Comparing predictive accuracy",
   J. Bus. Econ. Stat. 13 (1995) 253-263 (paired test on loss differences).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import SenscalError

__all__ = ["Candidate", "contiguous_blocks", "held_out_residuals", "held_out_norm_error", "paired_z", "choose", "Z_SIGNIFICANT",
           "N_BLOCKS"]

N_BLOCKS = 5
Z_SIGNIFICANT = 2.0  # k = 2: the richer model must be better by more than twice the standard error


@dataclass(frozen=True)
class Candidate(ResultMixin):
    """Evidence for one candidate model.

    Attributes
    ----------
    model : str
    n_params : int
        Free parameters fitted.
    n_identifiable : int
        Parameters the Fisher information determines (the others are reported
        as null, with the reason in ``unidentifiable``).
    unidentifiable : tuple of dict
        ``{"parameters", "reason"}`` groups of this model on these data.
    held_out_rms : float or None
        RMS of the held-out corrected-norm errors ``|H| / F - 1``
        (dimensionless; None: the model could not be fitted on some block,
        see ``error``).
    held_out_percent : float or None
        ``held_out_rms`` in %.
    block_rms : tuple of float
        The same per held-out block (its spread shows how stable it is).
    z_vs_best : float or None
        Paired z of the squared held-out residuals against the best model
        (0 for the best; > 2: significantly worse).
    error : str or None
        Why the model could not be evaluated.
    """

    model: str
    n_params: int
    n_identifiable: int
    unidentifiable: tuple[dict, ...]
    held_out_rms: float | None
    held_out_percent: float | None
    block_rms: tuple[float, ...]
    z_vs_best: float | None = None
    error: str | None = None


def contiguous_blocks(n: int, n_blocks: int = N_BLOCKS) -> list[np.ndarray]:
    """Indices of ``n_blocks`` contiguous, nearly equal blocks of ``range(n)``."""
    edges = np.linspace(0, n, n_blocks + 1).round().astype(int)
    return [np.arange(edges[k], edges[k + 1]) for k in range(n_blocks)]


def held_out_residuals(h: np.ndarray, fit: Callable[[np.ndarray], object],
                       predict: Callable[[object, np.ndarray], np.ndarray],
                       n_blocks: int = N_BLOCKS) -> tuple[np.ndarray, tuple[float, ...]]:
    """Residuals of each block predicted by a fit on the other blocks.

    Parameters
    ----------
    h : ndarray, shape (3, N)
        Readings in time order.
    fit : callable
        ``fit(h_train) -> fitted`` (may raise :class:`SenscalError`).
    predict : callable
        ``predict(fitted, h_test) -> residuals`` (sensor units).

    Returns
    -------
    r : ndarray, shape (N,)
        Held-out residual of every reading, in time order.
    block_rms : tuple of float
    """
    n = h.shape[1]
    r = np.empty(n)
    per = []
    for te in contiguous_blocks(n, n_blocks):
        tr = np.setdiff1d(np.arange(n), te)
        f = fit(h[:, tr])
        r[te] = predict(f, h[:, te])
        per.append(float(np.sqrt(np.mean(r[te] ** 2))))
    return r, tuple(per)


def held_out_norm_error(cal, h: np.ndarray, axes: tuple[int, int] | None = None,
                        h_train: np.ndarray | None = None) -> np.ndarray:
    """Relative error of the corrected field norm of readings a calibration corrects.

    Parameters
    ----------
    cal : TriaxialCalibration
        Fitted on other readings.
    h : ndarray, shape (3, N)
        Raw readings, sensor units.
    axes : (int, int), optional
        Judge the norm of these two corrected axes only (a turn about the
        third axis, where the readings determine the in-plane field and
        every candidate is compared on it); the reference is then the mean
        corrected in-plane norm of ``h_train``.
    h_train : ndarray, shape (3, M), optional
        The readings the calibration was fitted on (needed with ``axes``).

    Returns
    -------
    ndarray, shape (N,)
        Dimensionless: ``|H| / F - 1`` (all three axes, ``F`` the field the
        calibration promises), or ``|H_plane| / mean_train |H_plane| - 1``.
    """
    c = cal.apply(h)
    if axes is None and cal.model == "planar":
        i, j = cal.plane_axes  # it corrects only these two: its field is the in-plane one
        return np.hypot(c[i], c[j]) / float(cal.field) - 1.0
    if axes is None:
        return np.linalg.norm(c, axis=0) / float(cal.field) - 1.0
    i, j = axes
    ct = cal.apply(h_train)
    return np.hypot(c[i], c[j]) / float(np.mean(np.hypot(ct[i], ct[j]))) - 1.0


def paired_z(r_a: np.ndarray, r_b: np.ndarray) -> float:
    """Paired z of ``mean(r_a^2 - r_b^2)``: how many standard errors model a is worse than b."""
    d = np.asarray(r_a, float) ** 2 - np.asarray(r_b, float) ** 2
    sd = float(np.std(d, ddof=1)) if d.size > 1 else 0.0
    m = float(np.mean(d))
    if sd == 0.0:
        return 0.0 if m == 0 else math.copysign(math.inf, m)
    return m / (sd / math.sqrt(d.size))


def choose(candidates: Sequence[Candidate], residuals: dict[str, np.ndarray]
           ) -> tuple[str | None, list[Candidate], list[str]]:
    """The simplest candidate not significantly worse, held out, than the best.

    Parameters
    ----------
    candidates : sequence of Candidate
        Evaluated candidates (``held_out_rms`` None for failed ones).
    residuals : dict
        Model -> held-out residuals (same readings for every model).

    Returns
    -------
    chosen : str or None
        None when no candidate could be evaluated.
    candidates : list of Candidate
        With ``z_vs_best`` filled in.
    reasons : list of str
        One line per model not chosen, saying why.
    """
    ok = [c for c in candidates if c.held_out_rms is not None and c.model in residuals]
    if not ok:
        return None, list(candidates), [f"{c.model}: {c.error}" for c in candidates]
    best = min(ok, key=lambda c: c.held_out_rms)
    out = []
    for c in candidates:
        if c.model in residuals and c.held_out_rms is not None:
            z = 0.0 if c is best else paired_z(residuals[c.model], residuals[best.model])
            c = Candidate(**{**c.__dict__, "z_vs_best": float(z)})
        out.append(c)
    # Fewest parameters first; ties broken by held-out error.
    ranked = sorted((c for c in out if c.z_vs_best is not None), key=lambda c: (c.n_params, c.held_out_rms))
    chosen = next(c for c in ranked if c.z_vs_best <= Z_SIGNIFICANT)
    reasons = []
    for c in out:
        if c.model == chosen.model:
            continue
        if c.z_vs_best is None:
            reasons.append(f"{c.model}: {c.error}")
        elif c.z_vs_best > Z_SIGNIFICANT:
            reasons.append(f"{c.model}: held-out error {c.held_out_percent:.3g} % is significantly larger than "
                           f"{best.model}'s {best.held_out_percent:.3g} % (paired z = {c.z_vs_best:.3g})")
        else:
            reasons.append(f"{c.model}: held-out error {c.held_out_percent:.3g} % is no better than "
                           f"{chosen.model}'s {next(x for x in out if x.model == chosen.model).held_out_percent:.3g} "
                           f"% within the noise, with more parameters")
    return chosen.model, out, reasons


def safe(fn: Callable, *a, **kw):
    """``fn(*a, **kw)`` or the one-line message of the senscal error it raised."""
    try:
        return fn(*a, **kw), None
    except SenscalError as exc:
        return None, str(exc)
