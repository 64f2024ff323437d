"""Calibrate a three-axis sensor: diagnostics, model choice, fit, checks.

References
----------
.. [1] "三轴磁敏传感器转向误差建模与辨识" (Steering-error modelling and
   identification of a three-axis magnetic sensor), seed 004, METHODS.md s. 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.consistency import block_consistency
from senscal.diagnostics import named
from senscal.errors import (
    ConvergenceError, DegenerateGeometryError, DiagnosticError, InputError, SenscalError, TooFewSamplesError,
)
from senscal.triaxial import diagnostics as dg
from senscal.triaxial.estimators import (
    PAIR_ANGLE, ModelFit, _calibration, _design, _linear_problem, fit_algebraic, fit_linear, fit_lms, fit_ml, param_names,
    residuals,
)
from senscal.triaxial.heading import heading_report
from senscal.triaxial.models import MODELS, TriaxialCalibration
from senscal.triaxial.timeterms import BIAS_LIMIT_U, DRIFT_NAMES, fit_with_terms, session_time, term_evidence
from senscal.triaxial.selection import (
    N_BLOCKS, Z_SIGNIFICANT, Candidate, choose, held_out_norm_error, held_out_residuals, paired_z, safe,
)

__all__ = ["TriaxialResult", "calibrate", "METHODS", "nominal_raw"]

METHODS = ("auto", "lms", "linear", "ellipsoid", "ml")
ANGLES = ("alpha", "beta", "gamma")


@dataclass(frozen=True)
class TriaxialResult(ResultMixin):
    """Everything a three-axis calibration found out.

    Attributes
    ----------
    model, method : str
        Model fitted and estimator used.
    calibration : TriaxialCalibration
        What to apply to new data.
    parameters : dict
        Name -> ``{"value", "u", "unit"}`` (k=1; angles in rad).  Parameters
        the data cannot determine have value and u None (NaN).
    unidentifiable : tuple of dict
        ``{"parameters": [...], "reason": str}`` for the full model on these
        data (and for the fitted model, if it was forced).
    model_choice : tuple of str
        Why each other model was not chosen (held-out evidence, or why it could not be evaluated).
    field, field_estimated, scale_note :
        Field magnitude used (field units); when estimated the overall scale
        is arbitrary and ``scale_note`` says so.
    coverage, planarity, conditioning : dict
        Pre-fit diagnostics.
    noise : float
        Residual standard deviation per sample (sensor units).
    norm_error_before, norm_error_after : dict
        ``|H| - F`` statistics of the raw and corrected samples used.
    outliers, saturated : tuple of int
        Sample indices excluded (gross errors; clipped axes).
    plausibility : tuple of str
        Values outside the usual physical range (angles above 5 deg, gain
        ratios outside [0.8, 1.25], offsets above half the axis response)
        that the data do not establish (named ``implausible-parameters``).
    time_terms : dict or None
        Slow changes during the session (:mod:`senscal.triaxial.timeterms`):
        ``drift`` and ``step`` tests (F, p, adopted), the adopted terms'
        values with u (``terms``; the parameters are then those of the model
        with the terms: offsets at mid-session, field the session average), the
        bound on what an undetected term could do to the quoted parameters
        (``bias_bound``), and the first-half / second-half refit
        (``consistency``).  None for the planar and linearised fits.
    plausibility_supported : tuple of str
        Values outside that range which the data do establish (beyond it by
        more than 2 u, and the model without the term corrects held-out
        blocks significantly worse): a property of this sensor, not flagged.
    warnings : tuple of str
    lms_vs_least_squares : dict or None
        For ``method="lms"``: LMS minus least squares per weight, in units of
        the least-squares standard uncertainty.
    n_samples, n_used : int
    model_evidence : tuple of dict
        Automatic choice: per candidate model, its parameters, how many the
        Fisher information determines, its unidentifiable groups and its
        held-out error over 5 contiguous time blocks (see
        :mod:`senscal.triaxial.selection`).
    linearisation_bias : dict or None
        ``--method linear``/``lms``: linearised least-squares weights minus
        the exact maximum-likelihood fit's, per weight and in units of the
        least-squares u (``in_u``, ``max_abs_in_u``).
    heading : dict or None
        For a turn about one axis (or with an accelerometer): heading error
        before and after calibration (see :mod:`senscal.triaxial.heading`).
    """

    model: str
    method: str
    calibration: TriaxialCalibration
    parameters: dict[str, dict[str, Any]]
    unidentifiable: tuple[dict[str, Any], ...]
    model_choice: tuple[str, ...]
    field: float
    field_estimated: bool
    scale_note: str | None
    coverage: dict[str, Any]
    planarity: dict[str, Any]
    conditioning: dict[str, Any]
    noise: float
    norm_error_before: dict[str, float]
    norm_error_after: dict[str, float]
    outliers: tuple[int, ...]
    saturated: tuple[int, ...]
    plausibility: tuple[str, ...]
    warnings: tuple[str, ...]
    lms_vs_least_squares: dict[str, Any] | None
    n_samples: int
    n_used: int
    model_evidence: tuple[dict[str, Any], ...] = ()
    heading: dict[str, Any] | None = None
    linearisation_bias: dict[str, Any] | None = None
    plausibility_supported: tuple[str, ...] = ()
    time_terms: dict[str, Any] | None = None

    def value(self, name: str) -> float:
        """A parameter's value (NaN if unidentifiable)."""
        v = self.parameters[name]["value"]
        return math.nan if v is None else float(v)

    def u(self, name: str) -> float:
        """A parameter's standard uncertainty (NaN if none)."""
        v = self.parameters[name]["u"]
        return math.nan if v is None else float(v)


def nominal_raw(h: np.ndarray, field: float) -> tuple[np.ndarray, str | None]:
    """Raw readings for the 'before' figures.

    Readings already in field units are returned as they are.  Readings in
    other units (ADC counts: median magnitude more than 50 % off the field)
    get the nominal conversion a user would apply without calibration: the
    mid-range of each axis as zero and one common scale factor.

    Returns
    -------
    h : ndarray, shape like ``h``
    note : str or None
        Says what was done, when anything was.
    """
    h = np.asarray(h, float)
    med = float(np.median(np.linalg.norm(h, axis=0)))
    if med > 0 and abs(med / field - 1.0) <= 0.5:
        return h, None
    zero = 0.5 * (h.max(axis=1) + h.min(axis=1))
    c = h - zero[:, None]
    k = field / float(np.median(np.linalg.norm(c, axis=0)))
    return c * k, (f"raw readings are not in field units: 'before' uses the nominal conversion (mid-range of each "
                   f"axis as zero, one common factor {k:.6g})")


def _nominal_theta(model, k0, b0, f0, field, plane, r_plane):
    if model == "full":
        return np.array(([k0] * 3 if field else [1.0, 1.0]) + [0.0, 0.0, 0.0] + list(b0) + ([] if field else [f0]))
    if model == "diagonal":
        return np.array(([k0] * 3 if field else [1.0, 1.0]) + list(b0) + ([] if field else [f0]))
    if model == "offsets":
        return np.array(([k0] if field else []) + list(b0) + ([] if field else [f0]))
    i, j = plane
    return np.array([1.0, 0.0, b0[i], b0[j], r_plane])


def _column_condition(d: np.ndarray) -> float:
    """Condition number of a design matrix with its columns scaled to unit norm."""
    nrm = np.linalg.norm(d, axis=0)
    if np.any(nrm == 0):
        return math.inf
    sv = np.linalg.svd(np.linalg.qr(d / nrm, mode="r") if d.shape[0] > d.shape[1] else d / nrm, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf


def _model_design(model: str, x: np.ndarray, names, plane) -> np.ndarray:
    """Sensitivity of the squared magnitude to each parameter, on the measured centred data.

    Using the measured components (as the seed does) keeps exact
    collinearities exact: in one horizontal turn the measured Hz is constant,
    so the alpha column (Hx*Hz) is a multiple of the Bx column (Hx) whatever
    the gains are.
    """
    cols = {"Kx": x[0] ** 2, "Ky": x[1] ** 2, "Kz": x[2] ** 2, "K": np.sum(x * x, axis=0),
            "alpha": x[0] * x[2], "beta": x[1] * x[2], "gamma": x[0] * x[1],
            "Bx": x[0], "By": x[1], "Bz": x[2], "field": np.ones(x.shape[1]), "plane_field": np.ones(x.shape[1])}
    if plane is not None:
        i, j = plane
        ax = "xyz"
        cols = {f"K{ax[i]}": x[i] ** 2, PAIR_ANGLE[(i, j)]: x[i] * x[j], f"B{ax[i]}": x[i], f"B{ax[j]}": x[j],
                "plane_field": np.ones(x.shape[1])}
    return np.column_stack([cols[n] for n in names])


def _noise_floor(h: np.ndarray, b0: np.ndarray, r0: float, plane: tuple[int, int] | None) -> float:
    """Per-sample noise (sensor units) from a free quadric fit, or a free conic in the plane of planar data.

    A free quadric through nearly planar points absorbs the out-of-plane
    noise exactly, so planar data use the in-plane conic instead.
    """
    x = (h - b0[:, None]) / r0
    if plane is not None:
        a, b = x[list(plane)]
        d = np.column_stack([a * a, b * b, a * b, a, b])
        rho = float(np.median(np.hypot(a, b)))
    else:
        a, b, c = x
        d = np.column_stack([a * a, b * b, c * c, a * b, a * c, b * c, a, b, c])
        rho = 1.0
    # x'Ax + b'x = 1 near a circle/sphere of radius rho: the algebraic residual
    # is the gradient (2 / rho) times the radial error.
    y = np.ones(x.shape[1])
    w, _, rank, _ = np.linalg.lstsq(d, y, rcond=1e-9)
    dof = y.size - rank
    if dof < 1:
        return 1e-9 * r0
    res = y - d @ w
    return max(0.5 * rho * float(np.sqrt(res @ res / dof)) * r0, 1e-9 * r0)


# Coverage of an N(delta, 1) estimate by +-2 stays >= 93 % (the project's lower limit) while
# |delta| <= 0.43: a larger bias makes the k=2 interval miss too often.
LINEARISATION_LIMIT_U = 0.43


def _linearisation_bias(h: np.ndarray, model: str, field: float | None, lin: ModelFit) -> dict[str, Any] | None:
    """Linearised least-squares weights minus the exact model's, in units of their standard uncertainty.

    The exact maximum-likelihood fit of the same model (``full``, ``diagonal``
    or ``offsets``) is mapped to the seed's weights (``dK = K - 1``, angles,
    offsets, field); its own noise is far below the linearised fit's u, so
    the difference is the linearisation (second-order) error.
    """
    try:
        ex = fit_ml(h, model, field=field)
    except (DegenerateGeometryError, TooFewSamplesError, ConvergenceError):
        return None
    ev = dict(zip(ex.names, ex.values))
    if "K" in ev:
        ev.setdefault("Kx", ev["K"])
        ev.setdefault("Ky", ev["K"])
    exact = {"dKx": ev.get("Kx", 1.0) - 1.0, "dKy": ev.get("Ky", 1.0) - 1.0, "field": ex.field}
    exact.update({n: ev.get(n, 0.0) for n in ("alpha", "beta", "gamma", "Bx", "By", "Bz")})
    d, du = {}, {}
    for n, v, u in zip(lin.names, lin.values, lin.uncertainties):
        d[n] = float(v - exact[n])
        du[n] = float(d[n] / u) if np.isfinite(u) and u > 0 else None
    worst = max((abs(x) for x in du.values() if x is not None), default=0.0)
    return {"difference": d, "in_u": du, "max_abs_in_u": worst, "limit_in_u": LINEARISATION_LIMIT_U}


def _param_units(names, unit: str, field_known: bool) -> dict[str, str]:
    out = {}
    for n in names:
        if n in ANGLES:
            out[n] = "rad"
        elif n.startswith("dK") or (n.startswith("K") and not field_known):
            out[n] = "1"
        elif n.startswith("K"):
            out[n] = f"{unit or 'sensor unit'} per field unit"
        else:
            out[n] = unit
    return out


def _time_analysis(chosen: str, fit: ModelFit, h: np.ndarray, tau: np.ndarray, field: float | None, report: set,
                   prior, unit: str, channels, refit_static) -> tuple[ModelFit, dict[str, Any], list[str]]:
    """Offset drift and field step by evidence, what an undetected one could hide, and the halves refit.

    Returns the fit to report (with the adopted terms, if any), the
    ``time_terms`` report and the named warnings.
    """
    warns: list[str] = []
    try:
        ev = term_evidence(chosen, h, tau, field, fit.names, fit.values, report, prior)
    except (np.linalg.LinAlgError, ValueError, SenscalError) as exc:
        return fit, {"error": f"time terms not evaluated: {exc}"}, warns
    us = f" {unit}" if unit else ""
    rep: dict[str, Any] = {"drift": ev["drift"], "step": ev["step"], "alpha": ev["alpha"],
                           "bias_bound": ev["bias_bound"], "bias_limit_in_u": BIAS_LIMIT_U, "terms": {}}
    tf = ev["fit"]
    p = len(fit.names)
    if tf is not None:
        vals, cov = tf.values, tf.covariance
        for k in range(p, len(tf.names)):
            rep["terms"][tf.names[k]] = {"value": float(vals[k]), "u": float(math.sqrt(max(cov[k, k], 0.0))),
                                         "unit": unit}
        cal = _calibration(chosen, fit.method, vals[:p], field, None, unit, channels)
        fit = ModelFit(model=fit.model, method=fit.method, names=fit.names, values=vals[:p], covariance=cov[:p, :p],
                       calibration=cal, noise=float(math.sqrt(tf.rss / max(tf.dof, 1))), field=float(cal.field),
                       field_estimated=fit.field_estimated, n_used=fit.n_used)
    for term, c in ev["confounded"].items():
        what = "an offset drift" if term == "drift" else "a field step"
        adopted = ev[term]["adopted"]
        warns.append(named("time-confounded", (
            f"these orientations, in their time order, cannot tell {what} from {c['worst']}: "
            + (f"the {term} found is modelled, and the answer rests on its assumed shape in time (linear drift, "
               "one step)" if adopted else
               f"one too small to detect would shift {c['worst']} by about {c['bias_in_u']:.3g} of its u (the "
               "quoted u assume none)")
            + "; turn the sensor through the orientations in random order (with few readings: more of them), or "
              "return to the first orientations at the end of the session")))
    # The two halves of the session (or before / after an adopted step) fitted apart must agree within their u.
    n = h.shape[1]
    cut = int(np.searchsorted(tau, ev["step"]["at_fraction"] - 0.5)) if ev["step"]["adopted"] else n // 2
    cut = min(max(cut, 1), n - 1)
    parts = [np.arange(cut), np.arange(cut, n)]
    comp = [nm for nm in fit.names if nm in report and not (ev["step"]["adopted"] and nm == "field")]

    def block_fit(part: np.ndarray) -> dict[str, tuple[float, float]]:
        if len(part) <= 2 * p:
            raise TooFewSamplesError(f"{len(part)} readings in a block")
        try:
            if ev["drift"]["adopted"]:
                f_ = fit_with_terms(chosen, h[:, part], tau[part], field, fit.names, fit.values, True, None, prior)
                v_, c_ = f_.values[:p], f_.covariance[:p, :p]
            else:
                f_ = refit_static(h[:, part])
                v_, c_ = f_.values, f_.covariance
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ConvergenceError(str(exc)) from None
        return {nm: (float(v_[k]), float(math.sqrt(max(c_[k, k], 0.0))))
                for k, nm in enumerate(fit.names) if nm in comp}

    # senscal.consistency: each quantity's block estimates against their own u (chi-square, Bonferroni over
    # the quantities, 1 % false alarms in all).
    bc = block_consistency(block_fit, parts)
    split = "before / after the step" if ev["step"]["adopted"] else "halves"
    rep["consistency"] = {"split": split, **bc.to_dict()}
    if bc.n_blocks < 2:
        rep["consistency"]["error"] = "a block could not be fitted on its own"
    elif not bc.consistent:
        parts_txt = ("the readings before and after the field step" if ev["step"]["adopted"] else
                     "the first and the second half of the session")
        bad = ", ".join(f"{q.name} (Birge ratio {q.birge_ratio:.2g}, p = {q.p_value:.1g})" for q in bc.failing)
        warns.append(named("inconsistent-blocks", (
            f"{parts_txt} fitted apart give different {bad} than their own u allow: the sensor or the field "
            "changed during the session in a way the model does not follow, so the quoted u understate the error; "
            "keep the sensor's temperature and surroundings steady")))
    if tf is not None:
        terms = ", ".join(f"{k} = {v['value']:.4g} +/- {2 * v['u']:.2g}" for k, v in rep["terms"].items())
        rep["note"] = (f"slow changes during the session modelled ({terms}{us}, k=2): offsets are mid-session "
                       "values" + (", the field is the session average" if ev["step"]["adopted"] else ""))
    return fit, rep, warns


def calibrate(h: np.ndarray, *, field: float | None = None, method: str = "auto", model: str | None = None,
              lr: float = 0.01, epochs: int = 50, strict: bool = False, outlier_sigma: float | None = 5.0,
              min_coverage: float = 0.25, planar_thickness: float = 0.05, max_angle_deg: float = 5.0,
              gain_ratio: tuple[float, float] = (0.8, 1.25), max_offset: float = 0.5, unit: str = "",
              channels: Sequence[str] = ("x", "y", "z"), time_terms: bool = True) -> TriaxialResult:
    """Calibrate a three-axis magnetometer or accelerometer without a reference.

    Parameters
    ----------
    h : array_like, shape (3, N)
        Readings in a constant field (magnetometer) or static poses in
        gravity (accelerometer), sensor units, axes X, Y, Z.
    field : float, optional
        Field magnitude (e.g. 50,000 nT, local g in m/s^2).  None: estimated;
        the overall scale is then arbitrary (gains relative to Z).
    method : {"auto", "ml", "ellipsoid", "linear", "lms"}
        ``ml``/``auto``: algebraic ellipsoid start, maximum likelihood on the
        magnitude; ``ellipsoid``: algebraic only; ``linear``: the seed's
        linearised model by least squares; ``lms``: the same by the seed's
        LMS neuron (``lr``, ``epochs``).
    model : {"full", "diagonal", "offsets", "planar"}, optional
        Force a model.  None: chosen by held-out error over 5 contiguous
        time blocks (:mod:`senscal.triaxial.selection`); the linearised
        methods take the richest of their models the data determine.
    strict : bool
        Raise :class:`DiagnosticError` (exit 3) on insufficient coverage or
        implausible parameters instead of warning.
    outlier_sigma : float or None
        Samples whose corrected magnitude is more than this many robust
        standard deviations off are excluded and the fit repeated once.
    min_coverage : float
        Fraction of equal-area sphere cells below which coverage is called
        insufficient for the full model.
    planar_thickness : float
        Principal-axis spread ratio below which the noise floor and rough
        centre are measured in the plane.  Whether the data are a turn about
        one axis is decided from the Fisher information instead
        (``planarity["planar"]``, ``planarity["evidence"]``).
    max_angle_deg, gain_ratio, max_offset :
        Plausibility limits (see :func:`diagnostics.plausibility`).
    unit : str
        Sensor unit (for reports).
    channels : sequence of str
        Channel names (for the saved calibration).
    time_terms : bool
        Test the readings, in time order, for an offset drift and a field
        step, add the terms the data ask for, name what the data cannot tell
        from the parameters (``time-confounded``) and refit the two halves
        of the session against their stated u (``inconsistent-blocks``).
        Exact 3-D models only.

    Returns
    -------
    TriaxialResult

    References
    ----------
    .. [1] seed 004, METHODS.md section 5.
    """
    h = np.asarray(h, float)
    if h.ndim != 2 or h.shape[0] != 3:
        raise InputError(f"readings must have shape (3, N) for axes X, Y, Z; got {h.shape}")
    if not np.all(np.isfinite(h)):
        raise InputError("readings contain NaN or inf; remove them before calibrating")
    if h.size and float(np.max(np.abs(h))) > 1e150:
        # The ellipsoid fit works with squares and products of readings: beyond 1e154 they overflow float64.
        raise InputError(f"readings reach {float(np.max(np.abs(h))):.3g}, too large for the fit (their squares "
                         "overflow); check the unit or remove the corrupt readings")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    if model is not None and model not in MODELS:
        raise InputError(f"unknown model {model!r}; use one of {', '.join(MODELS)}")
    if field is not None and not (math.isfinite(field) and field > 0):
        raise InputError(f"field magnitude must be a positive number, got {field!r}")
    if outlier_sigma is not None and not (math.isfinite(outlier_sigma) and outlier_sigma > 0):
        raise InputError(f"the outlier threshold must be a positive number of robust sigmas, got {outlier_sigma!r}")
    n_total = h.shape[1]
    if n_total < 5:
        raise TooFewSamplesError(f"got {n_total} readings; even the simplest (offsets) model needs at least 5 "
                                 "orientations")
    linear_method = method in ("linear", "lms")
    warnings: list[str] = []

    sat_mask, sat_axes = dg.saturated_samples(h)
    if sat_mask.any():
        warnings.append(named("saturated", f"{int(sat_mask.sum())} samples with a saturated axis "
                        f"({', '.join('XYZ'[int(k)] for k in sat_axes)}) were excluded"))
    idx = np.flatnonzero(~sat_mask)
    hu = h[:, idx]
    if hu.shape[1] < 5:
        raise TooFewSamplesError(f"only {hu.shape[1]} readings left after removing saturated samples; "
                                 "reduce the field range or use a sensor range that does not clip")

    # -- before fitting: what can these data support? --------------------------
    plan = dg.planarity(hu)
    is_planar = plan["thickness"] < planar_thickness
    plane = plan["plane_axes"]
    b0 = dg.nominal_center(hu, is_planar, plane)
    r0 = float(np.median(np.linalg.norm(hu - b0[:, None], axis=0)))
    if not r0 > 0:
        raise DegenerateGeometryError("all readings are identical; turn the sensor through many orientations")
    if field is not None and not 1e-6 < r0 / field < 1e6:
        # Gains this far from 1 are a unit mix-up, and the solvers lose all precision on them.
        raise InputError(f"--field {field:g} does not match the readings (their magnitude is about {r0:.3g}); "
                         "give the field in the unit of the data")
    k0, f0 = (r0 / field, field) if field is not None else (1.0, r0)
    i, j = plane
    r_plane = float(np.median(np.hypot(hu[i] - b0[i], hu[j] - b0[j])))
    cov = dg.sphere_coverage(hu - b0[:, None])
    sigma_fit = _noise_floor(hu, b0, r0, plane if is_planar else None)
    q_step = dg.quantisation_step(hu)
    # A quantised reading cannot scatter less than a uniform error of one step
    # (variance step^2 / 12); a free quadric can fit below that, so the floor
    # is the larger of the two.
    sigma_q = q_step / math.sqrt(12.0) if q_step is not None else 0.0
    sigma0 = max(sigma_fit, sigma_q)
    plan = {**plan, "planar": bool(is_planar), "thickness_threshold": planar_thickness}

    xs = (hu - b0[:, None]) / r0

    def analyse(mdl, sigma=None):
        pl_ = plane if mdl == "planar" else None
        names = param_names(mdl, field is not None, pl_)
        d = _model_design(mdl, xs, names, pl_)
        info = dg.identifiability(d, names, dg.physical_scales(names, 1.0), (sigma or sigma0) / r0)
        info["n_ok"] = hu.shape[1] > len(names)
        return names, _nominal_theta(mdl, k0, b0, f0, field, plane, r_plane), info

    analyses = {m: analyse(m) for m in MODELS}
    conditioning = {m: {"condition": a[2]["condition"], "rank": a[2]["rank"], "n_params": a[2]["n_params"]}
                    for m, a in analyses.items()}
    conditioning["noise_floor"] = sigma0
    conditioning["noise_floor_fit"] = sigma_fit
    conditioning["quantisation_step"] = q_step
    # The estimators' own matrices: the seed's linearised design (LMS / linear)
    # and the algebraic ellipsoid design, columns scaled to unit norm.
    def linear_analysis(mdl):
        xl, _, lnames, ls_scale = _linear_problem(hu, field, mdl)
        return xl, lnames, dg.identifiability(xl, lnames, dg.physical_scales(lnames, 1.0), sigma0 / ls_scale)

    xl, lnames, lin_info = linear_analysis("full")
    conditioning["linear_design"] = {"condition": _column_condition(xl), "rank": lin_info["rank"],
                                     "n_params": len(lnames), "groups": lin_info["groups"]}
    conditioning["ellipsoid_design"] = {"condition": _column_condition(_design("full", xs)), "n_params": 9}
    unidentifiable = list(analyses["full"][2]["groups"])

    # -- which model? ----------------------------------------------------------
    # A turn about one axis: every model is scored on the two in-plane axes (see selection).
    score_axes = tuple(plane) if plan["normal_alignment"] >= 0.95 and is_planar else None
    choice: list[str] = []
    candidates: list = []
    fits_all: dict[str, ModelFit] = {}

    def weak_of(mdl: str) -> set:
        return {p for g in analyses[mdl][2]["groups"] for p in g["parameters"]}

    def prior_for(mdl: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Directions the data cannot see, pinned weakly at the nominal point.

        One noise floor (sensor units, like the residuals) per plausible
        range, so that the fit converges; they are reported as unknown.
        """
        weak_ = weak_of(mdl)
        if not weak_:
            return None
        names_ = analyses[mdl][0]
        sc = dg.physical_scales(names_, f0 if mdl != "planar" else r_plane, k0 if mdl != "planar" else 1.0)
        wt = np.array([sigma0 / s_ if n in weak_ else 0.0 for n, s_ in zip(names_, sc)])
        return analyses[mdl][1], wt

    def fit_model(hh: np.ndarray, mdl: str, warm: np.ndarray | None = None, quick: bool = False) -> ModelFit:
        """Maximum-likelihood (or ellipsoid) fit of an exact model, directions the data cannot see pinned.

        ``warm``: start there.  ``quick``: a prediction-only fit (candidates
        and cross-validation folds): loose tolerance, capped evaluations, no
        covariance; the chosen model is refitted in full from its answer.
        """
        pl_ = plane if mdl == "planar" else None
        weak_ = weak_of(mdl)
        if warm is not None and method != "ellipsoid":
            start = None
        else:
            try:
                start = fit_algebraic(hh, mdl, field=field, plane=pl_, unit=unit, channels=channels)
            except DegenerateGeometryError:
                if method == "ellipsoid":
                    raise
                start = None
        if method == "ellipsoid":
            return start
        prior = prior_for(mdl)
        theta0 = start.values if start is not None else analyses[mdl][1]
        if prior is not None:
            theta0 = analyses[mdl][1]
        if warm is not None:
            theta0 = warm
        return fit_ml(hh, mdl, field=field, plane=pl_, start=theta0, unit=unit, channels=channels, prior=prior,
                      tol=1e-7 if quick else 1e-12, with_covariance=not quick,
                      max_nfev=(20 if warm is not None else 60) * (len(analyses[mdl][0]) + 1) if quick else None)

    if model is not None:
        chosen = model
        if linear_method and chosen == "planar":
            raise InputError("the linearised (lms/linear) methods have no planar form; use --method ml or "
                             "ellipsoid with --model planar")
        groups = analyses[chosen][2]["groups"]
        if chosen != "full" and groups:
            unidentifiable += [dict(g, model=chosen) for g in groups]
        if not analyses[chosen][2]["n_ok"]:
            raise TooFewSamplesError(f"the {chosen} model has {len(analyses[chosen][0])} parameters and needs "
                                     f"more readings than that, got {hu.shape[1]}")
    elif linear_method:
        # The linearised methods have no planar form and no pinning: the
        # richest of their models the data determine.
        chosen = None
        for m in ("full", "diagonal", "offsets"):
            names, _, info = analyses[m]
            if not info["n_ok"]:
                choice.append(f"{m}: {len(names)} parameters need more than {hu.shape[1]} readings")
                continue
            if info["groups"]:
                choice.append(f"{m}: " + "; ".join(g["reason"] for g in info["groups"]))
                continue
            chosen = m
            break
        if chosen is None:
            raise DegenerateGeometryError("the orientations do not determine even the simplest model ("
                                          + " | ".join(choice) + "); turn the sensor through more orientations")
    else:
        resid: dict[str, np.ndarray] = {}
        n_train = hu.shape[1] - int(math.ceil(hu.shape[1] / N_BLOCKS))
        for m in ("full", "diagonal", "offsets", "planar"):
            names, _, info = analyses[m]
            groups = tuple(dict(g) for g in info["groups"])
            n_id = len(names) - len(weak_of(m))
            err = None
            if not info["n_ok"]:
                err = f"{len(names)} parameters need more than {hu.shape[1]} readings"
            elif n_train <= len(names):
                err = (f"{len(names)} parameters need more than the {n_train} readings of each "
                       f"{N_BLOCKS}-block cross-validation fit")
            elif m == "planar" and plan["normal_alignment"] < 0.95:
                err = "the rotation plane is not close to a pair of sensor axes"
            elif n_id == 0:
                err = "no parameter is determined by these orientations"
            rms = pct = None
            per: tuple[float, ...] = ()
            if err is None:
                pl_ = plane if m == "planar" else None
                whole, err = safe(fit_model, hu, m, None, True)
                out = None
                if whole is not None:
                    # A centre farther from the cloud's own centre than its
                    # radius means the readings do not surround it: the fit
                    # has slid along a direction the data cannot see (e.g. a
                    # huge sphere whose cap mimics an ellipse in one plane).
                    ax_ = list(pl_) if pl_ is not None else [0, 1, 2]
                    rad_ = r_plane if pl_ is not None else r0
                    shift = float(np.linalg.norm(whole.calibration.offsets[ax_] - b0[ax_]))
                    if shift > rad_:
                        err = (f"its fitted centre lies {shift / rad_:.3g} cloud radii from the readings' centre: "
                               "the readings do not surround it")
                        whole = None
                if whole is not None:
                    fits_all[m] = whole
                    # Scored as a user sees the calibration: the corrected field norm of readings the fit
                    # has not seen, relative to the field it promises.
                    out, err = safe(held_out_residuals, hu,
                                    lambda hh, m=m, w=whole.values: (fit_model(hh, m, w, True), hh),
                                    lambda f_, ht: held_out_norm_error(f_[0].calibration, ht, score_axes, f_[1]))
                if out is not None:
                    if np.all(np.isfinite(out[0])):
                        resid[m], per = out
                    else:
                        err = "its held-out prediction is not finite (the fit is degenerate on some blocks)"
            candidates.append(Candidate(model=m, n_params=len(names), n_identifiable=n_id, unidentifiable=groups,
                                        held_out_rms=None, held_out_percent=None, block_rms=per, error=err))
        # Gross errors would dominate every model's held-out error: judge on
        # the readings the best model does not call outliers.
        keep = np.ones(hu.shape[1], bool)
        if resid and outlier_sigma is not None:
            best_m = min(resid, key=lambda k: float(np.mean(resid[k] ** 2)))
            keep[dg.robust_outliers(resid[best_m], outlier_sigma)] = False
        cands2 = []
        for c in candidates:
            if c.model in resid:
                rr = resid[c.model][keep]
                rms = float(np.sqrt(np.mean(rr ** 2)))
                c = Candidate(**{**c.__dict__, "held_out_rms": rms, "held_out_percent": 100.0 * rms})
            cands2.append(c)
        chosen, candidates, choice = choose(cands2, {k: v[keep] for k, v in resid.items()})
        if chosen is None:
            raise DegenerateGeometryError("the orientations do not determine even the simplest model ("
                                          + " | ".join(choice) + "); turn the sensor through more orientations")

    # -- fit -------------------------------------------------------------------
    pl = plane if chosen == "planar" else None

    def run_fit(hh: np.ndarray) -> tuple[ModelFit, ModelFit | None]:
        if method == "linear":
            return fit_linear(hh, field=field, model=chosen, unit=unit, channels=channels), None
        if method == "lms":
            ls = fit_linear(hh, field=field, model=chosen, unit=unit, channels=channels)
            return fit_lms(hh, field=field, model=chosen, lr=lr, epochs=epochs, unit=unit, channels=channels), ls
        if hh is hu and chosen in fits_all and method != "ellipsoid":
            return fit_model(hh, chosen, fits_all[chosen].values), None
        return fit_model(hh, chosen), None

    def norms(cal: TriaxialCalibration, hh: np.ndarray) -> np.ndarray:
        c = cal.apply(hh)
        return np.hypot(c[i], c[j]) if chosen == "planar" else np.linalg.norm(c, axis=0)

    weak_groups = linear_analysis(chosen)[2]["groups"] if linear_method else analyses[chosen][2]["groups"]
    weak = {p for g in weak_groups for p in g["parameters"]}
    fit, ls = run_fit(hu)
    outl = np.array([], int)
    if outlier_sigma is not None:
        outl = dg.robust_outliers(norms(fit.calibration, hu) - fit.field, outlier_sigma)
        n_par = len(fit.names)
        if outl.size and hu.shape[1] - outl.size > n_par:
            keep = np.setdiff1d(np.arange(hu.shape[1]), outl)
            warnings.append(named("outliers", f"{outl.size} outlier readings (more than {outlier_sigma:g} robust sigma off the "
                            "field magnitude) were excluded and the fit repeated"))
            hu2 = hu[:, keep]
            fit, ls = run_fit(hu2)
        else:
            hu2 = hu
            outl = np.array([], int)
    else:
        hu2 = hu

    # -- after fitting ---------------------------------------------------------
    # Identifiability again, at the data's own error level: the chosen fit's
    # residual scatter (not below the noise floor), inflated for serial
    # correlation.  Correlated residuals carry less information than as many
    # independent ones: for AR(1) with lag-1 correlation rho the variance of
    # a mean grows by (1 + rho) / (1 - rho).  A wobbling hand-held turn is
    # then seen for what it is: a one-axis turn whose wobble does not pin
    # down the out-of-plane parameters.
    evidence = {"sigma_noise_floor": sigma0}
    if not linear_method:
        r_fin = residuals(chosen, fit.values, hu2, field, pl)
        rho = float(np.corrcoef(r_fin[:-1], r_fin[1:])[0, 1]) if r_fin.size > 3 and np.std(r_fin) > 0 else 0.0
        rho = min(max(rho, 0.0), 0.99) if math.isfinite(rho) else 0.0
        sigma_eff = max(sigma0, fit.noise) * math.sqrt((1 + rho) / (1 - rho))
        evidence.update({"sigma_residual": float(fit.noise), "residual_lag1_correlation": rho,
                         "sigma_effective": sigma_eff})
        analyses_eff = {m: analyse(m, sigma_eff) for m in MODELS}
        unidentifiable = list(analyses_eff["full"][2]["groups"])
        if model is not None and chosen != "full":
            unidentifiable += [dict(g, model=chosen) for g in analyses_eff[chosen][2]["groups"]]
        weak = weak | {p for g in analyses_eff[chosen][2]["groups"] for p in g["parameters"]}
        if chosen in ("diagonal", "offsets") and analyses_eff["full"][2]["n_ok"]:
            # A simpler model only assumes the missing terms are zero: a
            # parameter the full model cannot tell from one of them (Bx from
            # alpha on a level turn) is not determined here either, whatever
            # this model's own information says.  (The planar model's
            # parameters are in-plane combinations that include the leakage,
            # so they stay.)
            tied = {p for g in analyses_eff["full"][2]["groups"] for p in g["parameters"]}
            extra = [n for n in analyses[chosen][0] if n in tied and n not in weak]
            if extra:
                weak = weak | set(extra)
                unidentifiable.append({"parameters": extra, "model": chosen, "reason": (
                    f"{', '.join(extra)} cannot be told from terms the {chosen} model assumes zero (see the full "
                    "model's groups): not determined by these orientations")})
        candidates = [Candidate(**{**c.__dict__, "unidentifiable": tuple(analyses_eff[c.model][2]["groups"]),
                                   "n_identifiable": len(analyses_eff[c.model][0]) - len(
                                       {p for g in analyses_eff[c.model][2]["groups"] for p in g["parameters"]})})
                      for c in candidates]
        full_groups = analyses_eff["full"][2]["groups"]
    else:
        full_groups = analyses["full"][2]["groups"]
    # One-axis turn, by the Fisher information: an angle between the normal
    # axis and an in-plane axis cannot be told from that in-plane axis's
    # offset (the seed's alpha ~ Bx, beta ~ By for a level turn).
    k_n = plan["normal_axis"]
    one_axis = []
    for g in full_groups:
        for (a_, b_), ang in PAIR_ANGLE.items():
            if k_n in (a_, b_) and ang in g["parameters"]:
                other = b_ if a_ == k_n else a_
                if f"B{'xyz'[other]}" in g["parameters"]:
                    one_axis.append(f"{ang} ~ B{'xyz'[other]}")
    is_turn = bool(one_axis) and plan["normal_alignment"] >= 0.95
    plan = {**plan, "planar": is_turn, "evidence": {**evidence, "confounded_by_one_axis_turn": one_axis}}
    # -- slow changes during the session (offset drift, field step) ------------
    time_report, time_warn = None, []
    if time_terms and not linear_method and chosen in ("full", "diagonal", "offsets") and fit.covariance is not None:
        kept_ = np.setdiff1d(np.arange(hu.shape[1]), outl)
        tau2 = session_time(idx, n_total)[kept_]
        fit, time_report, time_warn = _time_analysis(
            chosen, fit, hu2, tau2, field, {n for n in fit.names if n not in weak}, prior_for(chosen), unit, channels,
            lambda hh: fit_model(hh, chosen))
        warnings.extend(time_warn)
    units = _param_units(fit.names, unit, field is not None and chosen != "planar")
    u_all = fit.uncertainties
    params = {}
    for n, v, u in zip(fit.names, fit.values, u_all):
        if n in weak:
            params[n] = {"value": None, "u": None, "unit": units[n]}
        else:
            params[n] = {"value": float(v), "u": float(u) if np.isfinite(u) else None, "unit": units[n]}
    if fit.field_estimated:
        scale_note = ("field magnitude estimated from the data: the overall scale is arbitrary (gains are relative "
                      "to the Z axis and the field is in Z-axis units)") if chosen != "planar" else (
            "planar model: the in-plane field magnitude is estimated and the in-plane scale is arbitrary "
            f"(K{'xyz'[j]} = 1); the {'XYZ'[plan['normal_axis']]} axis is left uncorrected, and the in-plane offsets "
            "include the constant out-of-plane field leaking through the non-orthogonality (e.g. Bx + "
            "Kx sin(alpha) cos(gamma) Hz)")
    else:
        scale_note = None
    raw, raw_note = nominal_raw(hu2[[i, j]] if chosen == "planar" else hu2, fit.field)
    before = dg.norm_error_stats(np.linalg.norm(raw, axis=0), fit.field)
    if raw_note:
        before["note"] = raw_note
    after = dg.norm_error_stats(norms(fit.calibration, hu2), fit.field)
    plaus_params = {n: (v["value"] if v["value"] is not None else math.nan) for n, v in params.items()}
    if chosen == "planar":
        plaus_params[f"K{'xyz'[j]}"] = 1.0
        plaus_params.setdefault("Kz", 1.0)
    # Raw counts carry the converter's zero in their offsets: only judge offsets
    # of data already in field units.
    plaus_u = {n: v["u"] for n, v in params.items() if v["u"] is not None}
    checks = dg.plausibility_checks(plaus_params, fit.field, max_angle_deg=max_angle_deg, gain_ratio=gain_ratio,
                                    max_offset=max_offset if raw_note is None else None, u=plaus_u)
    # A value outside the usual range is a property of this sensor when the data say so: it lies beyond
    # the range by more than k = 2 of its u, and (gains, angles) the chosen model corrects unseen time
    # blocks significantly better (paired z > 2, as in the model choice) than the model without that
    # term (equal gains: offsets; no angles: diagonal).  Otherwise it is flagged as implausible.
    plaus, supported = [], []
    held: dict[str, np.ndarray | None] = {}

    def held_out_of(mdl: str) -> np.ndarray | None:
        if mdl not in held:
            out_, _ = safe(held_out_residuals, hu2, lambda hh: (fit_model(hh, mdl, None, True), hh),
                           lambda f_, ht: held_out_norm_error(f_[0].calibration, ht, score_axes, f_[1]))
            held[mdl] = out_[0] if out_ is not None and np.all(np.isfinite(out_[0])) else None
        return held[mdl]

    for c in checks:
        ok = c["excess_in_u"] is not None and c["excess_in_u"] > Z_SIGNIFICANT
        alt = {"gain": "offsets", "angle": "diagonal"}.get(c["kind"])
        z_alt = None
        if ok and alt is not None:
            if linear_method or chosen == "planar" or alt == chosen:
                ok = False
            else:
                r_c, r_a = held_out_of(chosen), held_out_of(alt)
                z_alt = None if r_c is None or r_a is None else paired_z(r_a, r_c)
                ok = z_alt is not None and z_alt > Z_SIGNIFICANT
        if ok:
            why = f"{c['excess_in_u']:.3g} u beyond the range" + (
                f"; without it ({alt} model) unseen blocks are corrected worse, paired z = {z_alt:.3g}"
                if z_alt is not None else "")
            supported.append(f"{c['message']}: determined by the data ({why})")
        else:
            plaus.append(c["message"])
    lin_bias = None
    if linear_method:
        lin_bias = _linearisation_bias(hu2, chosen, field, ls if ls is not None else fit)
        if lin_bias is not None and lin_bias["max_abs_in_u"] > LINEARISATION_LIMIT_U:
            worst_n = max((k for k, v in lin_bias["in_u"].items() if v is not None),
                          key=lambda k: abs(lin_bias["in_u"][k]))
            warnings.append(named("linearisation-error", (
                f"the seed's linearised model differs from the exact maximum-likelihood fit by up to "
                f"{lin_bias['max_abs_in_u']:.3g} standard uncertainties ({worst_n}): the dropped second-order terms "
                "are not in u, so the intervals of --method linear/lms do not cover; use --method ml (the default)")))
    lms_cmp = None
    if ls is not None:
        d = {}
        for n, v, lv, lu in zip(fit.names, fit.values, ls.values, ls.uncertainties):
            d[n] = float((v - lv) / lu) if lu > 0 else None
        worst = max((abs(x) for x in d.values() if x is not None), default=0.0)
        lms_cmp = {"difference_in_u": d, "max_abs_difference_in_u": worst, "epochs": epochs, "lr": lr,
                   "least_squares": {n: float(v) for n, v in zip(ls.names, ls.values)}}
        if worst > 1:
            warnings.append(named("lms-not-converged", f"LMS after {epochs} epochs is up to {worst:.3g} standard uncertainties from the "
                            "least-squares solution: it has not converged; use --method linear or more --epochs"))

    us = f" {unit}" if unit else ""
    if fit.noise > 1.5 * sigma0 and fit.n_used > 2 * len(fit.names):
        warnings.append(named("unmodelled-error", f"the {chosen} model leaves a residual of {fit.noise:.4g}{us} per "
                              f"sample against a noise floor of {sigma0:.4g}{us}: errors it does not model are not negligible, and its "
                        "uncertainties understate the real error"))
    coverage_problem = None
    if model in ("diagonal", "offsets", "planar"):
        if analyses[model][2]["groups"]:
            coverage_problem = f"the orientations cannot determine the forced {model} model"
    else:
        if unidentifiable:
            coverage_problem = "the orientations cannot determine the full model (" + "; ".join(
                g["reason"] for g in unidentifiable) + ")"
        elif cov["fraction"] < min_coverage:
            coverage_problem = (f"the directions hit {cov['fraction']:.0%} of the sphere cells, below "
                                f"{min_coverage:.0%}")
    if coverage_problem:
        warnings.append(named("insufficient-coverage", f"insufficient coverage: {coverage_problem}"))
    if plaus:
        warnings.append(named("implausible-parameters", "implausible parameters: " + "; ".join(plaus)))
    if strict and (coverage_problem or plaus or time_warn):
        what = "; ".join(([f"insufficient coverage: {coverage_problem}"] if coverage_problem else [])
                         + ([f"implausible parameters: {'; '.join(plaus)}"] if plaus else [])
                         + [w for w in time_warn])
        raise DiagnosticError(f"--strict: {what}; record more orientations or drop --strict to accept the "
                              f"{chosen} model")
    if linear_method and is_turn:
        warnings.append(named("planar-data-linearised", (
            f"these readings are a turn about one axis, and --method {method} has no planar form: it fell back to "
            f"the {chosen} model, which cannot represent the in-plane gain ratio and non-orthogonality the turn "
            "does determine (the seed's 8-weight neuron is not identifiable here either); use the default "
            "--method auto, or --model planar, for the in-plane model and its heading error")))
    kept = np.setdiff1d(np.arange(hu.shape[1]), outl)
    heading = None
    if is_turn and not linear_method and fit.covariance is not None:
        def corrected(th):
            return _calibration(chosen, fit.method, th, field, pl, unit, channels).apply(hu2)

        heading = heading_report(hu2, corrected, fit.values, fit.covariance, fit.noise, axes=tuple(plan["plane_axes"]))
    return TriaxialResult(
        model=chosen, method=fit.method, calibration=fit.calibration, parameters=params,
        unidentifiable=tuple(unidentifiable), model_choice=tuple(choice), field=float(fit.field),
        field_estimated=bool(fit.field_estimated), scale_note=scale_note, coverage=cov, planarity=plan,
        conditioning=conditioning, noise=float(fit.noise), norm_error_before=before, norm_error_after=after,
        outliers=tuple(int(idx[k]) for k in outl), saturated=tuple(int(k) for k in np.flatnonzero(sat_mask)),
        plausibility=tuple(plaus), plausibility_supported=tuple(supported), warnings=tuple(warnings),
        lms_vs_least_squares=lms_cmp,
        linearisation_bias=lin_bias,
        n_samples=int(n_total), n_used=int(kept.size),
        model_evidence=tuple(c.to_dict() for c in candidates), heading=heading, time_terms=time_report,
    )
