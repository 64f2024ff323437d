"""What the data can support, before fitting, and how good the fit is, after.

References
----------
.. [1] seed 004, METHODS.md section 5: one horizontal turn keeps Hz nearly
   constant, so the Hx*Hz term is proportional to Hx (alpha vs Bx) and
   Hy*Hz to Hy (beta vs By).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.sparse.csgraph import connected_components

__all__ = ["quantisation_step", "saturated_samples", "nominal_center", "sphere_coverage", "planarity", "identifiability",
           "norm_error_stats", "robust_outliers", "physical_scales", "plausibility", "plausibility_checks"]


def saturated_samples(h: np.ndarray, min_count: int = 3) -> tuple[np.ndarray, dict[str, int]]:
    """Samples where an axis sits at its extreme value more often than noise allows.

    A clipped axis piles samples up at exactly its largest (or smallest)
    value; a real extreme orientation only touches it a few times, spread
    over nearby values.  An extreme is called saturated when at least
    ``min_count`` samples sit exactly on it and they outnumber the samples in
    the next 1 % of the axis range.

    Returns
    -------
    mask : ndarray of bool, shape (N,)
        True for samples with any saturated axis.
    per_axis : dict
        Axis index (as str) -> number of saturated samples.
    """
    mask = np.zeros(h.shape[1], bool)
    per_axis = {}
    for k in range(3):
        x = h[k]
        rng = float(np.ptp(x))
        if rng == 0:
            continue
        for edge, sign in ((x.max(), 1), (x.min(), -1)):
            at = x == edge
            n_at = int(at.sum())
            near = (sign * (edge - x) > 0) & (sign * (edge - x) <= 0.01 * rng)
            if n_at >= min_count and n_at > int(near.sum()):
                mask |= at
                per_axis[str(k)] = per_axis.get(str(k), 0) + n_at
    return mask, per_axis


def planarity(h: np.ndarray) -> dict[str, Any]:
    """Principal-axis spread of the points.

    Returns
    -------
    dict
        ``thickness``: sqrt(smallest / largest principal variance) (1 for a
        sphere, 0 for points on a plane); ``normal``: unit normal of the best
        plane; ``normal_axis``: sensor axis closest to it; ``plane_axes``.
    """
    d = h - h.mean(axis=1, keepdims=True)
    lam, vec = np.linalg.eigh(d @ d.T / max(h.shape[1], 1))
    lam = np.clip(lam, 0.0, None)
    normal = vec[:, 0]
    k = int(np.argmax(np.abs(normal)))
    axes = tuple(i for i in range(3) if i != k)
    return {"thickness": float(math.sqrt(lam[0] / lam[2])) if lam[2] > 0 else 0.0,
            "normal": (normal * np.sign(normal[k])).tolist(), "normal_axis": k, "plane_axes": axes,
            "normal_alignment": float(abs(normal[k]))}


def _circle_center(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    d = np.column_stack([2 * a, 2 * b, np.ones_like(a)])
    c = np.linalg.lstsq(d, a * a + b * b, rcond=None)[0]
    return float(c[0]), float(c[1])


def nominal_center(h: np.ndarray, planar: bool, plane_axes: tuple[int, int]) -> np.ndarray:
    """A rough centre of the measured cloud (offsets) for the pre-fit diagnostics.

    Sphere least squares on 3-D data; on planar data the in-plane circle
    centre, and zero along the normal (the data cannot tell it).
    """
    if planar:
        i, j = plane_axes
        c = np.zeros(3)
        c[i], c[j] = _circle_center(h[i], h[j])
        return c
    mu = h.mean(axis=1, keepdims=True)
    x = h - mu
    d = np.column_stack([2 * x[0], 2 * x[1], 2 * x[2], np.ones(h.shape[1])])
    c = np.linalg.lstsq(d, np.sum(x * x, axis=0), rcond=None)[0]
    return c[:3] + mu[:, 0]


def sphere_coverage(u: np.ndarray, n_bands: int = 6, n_sectors: int = 12) -> dict[str, Any]:
    """Fraction of equal-area cells of the unit sphere hit by the directions.

    Cells are ``n_bands`` bands of equal height in z (equal area, by
    Archimedes' hat-box theorem) times ``n_sectors`` equal longitude sectors.
    """
    u = u / np.linalg.norm(u, axis=0)
    band = np.clip(((u[2] + 1) / 2 * n_bands).astype(int), 0, n_bands - 1)
    sector = np.clip(((np.arctan2(u[1], u[0]) + math.pi) / (2 * math.pi) * n_sectors).astype(int), 0,
                     n_sectors - 1)
    hit = np.unique(band * n_sectors + sector).size
    return {"fraction": hit / (n_bands * n_sectors), "cells_hit": int(hit), "cells": n_bands * n_sectors}


def physical_scales(names, field: float, gain: float = 1.0) -> np.ndarray:
    """The size of a plausible error in each parameter (5 % gain, 2 deg, 5 % of the field as offset)."""
    out = []
    for n in names:
        if n in ("alpha", "beta", "gamma"):
            out.append(math.radians(2.0))
        elif n.startswith("dK"):
            out.append(0.05)
        elif n.startswith("K"):
            out.append(0.05 * gain)
        elif n.startswith("B"):
            out.append(0.05 * gain * field)
        else:  # field, plane_field
            out.append(0.05 * field)
    return np.array(out)


_PAIR_REASONS = {
    frozenset({"alpha", "Bx"}): "alpha cannot be told from Bx: Hz is nearly constant, so the Hx*Hz term is "
                                "proportional to Hx",
    frozenset({"beta", "By"}): "beta cannot be told from By: Hz is nearly constant, so the Hy*Hz term is "
                               "proportional to Hy",
}


def identifiability(jac: np.ndarray, names, scales: np.ndarray, sigma: float) -> dict[str, Any]:
    """Which parameters (or combinations) the data cannot determine.

    The Jacobian of the residuals (noise units) is scaled by the plausible
    size of each parameter; a singular direction whose effect on the data is
    below the noise (``s_k < sigma``) cannot be pinned down better than its
    whole plausible range, so its parameters are unidentifiable.  Parameters
    tied by such directions are grouped (connected components of the
    null-space projector).

    Returns
    -------
    dict
        ``groups`` (list of ``{"parameters", "reason"}``), ``condition``
        (of the scaled matrix), ``rank`` (directions resolved), ``n_params``.
    """
    js = jac * scales[None, :]
    js = js[np.all(np.isfinite(js), axis=1)]
    if js.shape[0] == 0:
        return {"groups": [{"parameters": list(names), "reason": "no usable samples"}], "condition": math.inf,
                "rank": 0, "n_params": len(names)}
    # Only V is needed: reduce a tall matrix to its p x p triangle first (a
    # full U would be N x N).  With fewer rows than parameters, the full V
    # holds the null space.
    if js.shape[0] > js.shape[1]:
        js = np.linalg.qr(js, mode="r")  # same singular values and V, p x p
    _, s, vt = np.linalg.svd(js, full_matrices=True)
    s_full = np.zeros(len(names))
    s_full[: s.size] = s
    weak = s_full <= max(sigma, 1e-12 * (s_full[0] if s_full[0] > 0 else 1.0))
    cond = float(s_full[0] / s_full[-1]) if s_full[-1] > 0 else math.inf
    groups = []
    if weak.any():
        v0 = vt[weak].T
        proj = v0 @ v0.T
        involved = np.diag(proj) > 0.05
        adj = (np.abs(proj) > 0.05) & involved[:, None] & involved[None, :]
        ncomp, labels = connected_components(adj, directed=False)
        for c in range(ncomp):
            members = [names[k] for k in range(len(names)) if involved[k] and labels[k] == c]
            if not members:
                continue
            key = frozenset(members)
            if key in _PAIR_REASONS:
                reason = _PAIR_REASONS[key]
            elif len(members) == 1:
                reason = f"{members[0]} has no measurable effect on the field magnitude in these orientations"
            else:
                reason = (f"{', '.join(members)} are confounded: in these orientations only a combination of them "
                          "changes the field magnitude")
            groups.append({"parameters": members, "reason": reason})
    return {"groups": groups, "condition": cond, "rank": int((~weak).sum()), "n_params": len(names)}


def norm_error_stats(norm: np.ndarray, field: float) -> dict[str, float]:
    """Mean, standard deviation and largest absolute value of ``|H| - F`` (field units and %)."""
    e = np.asarray(norm, float) - field
    d = {"mean": float(e.mean()), "std": float(e.std(ddof=1)) if e.size > 1 else 0.0,
         "max_abs": float(np.max(np.abs(e)))}
    d.update({f"{k}_percent": 100.0 * v / field for k, v in list(d.items())})
    return d


def robust_outliers(e: np.ndarray, k: float) -> np.ndarray:
    """Indices where ``e`` is more than ``k`` robust standard deviations (1.4826 MAD) from its median."""
    med = np.median(e)
    mad = 1.4826 * np.median(np.abs(e - med))
    if not mad > 0:
        return np.array([], int)
    return np.flatnonzero(np.abs(e - med) > k * mad)


def plausibility_checks(params: dict[str, float], field: float, *, max_angle_deg: float = 5.0,
                        gain_ratio: tuple[float, float] = (0.8, 1.25), max_offset: float | None = 0.5,
                        u: dict[str, float] | None = None) -> list[dict[str, Any]]:
    """Physical-range checks on fitted parameters (angles in rad), one dict per value outside its usual range.

    Returns
    -------
    list of dict
        ``message``; ``kind`` (``angle``, ``gain``, ``offset``); ``parameter``;
        ``excess_in_u``: how many standard uncertainties the value lies
        beyond the range limit (None without ``u``), i.e. whether the data
        determine that it is outside.
    """
    u = u or {}
    issues = []

    def excess(dist: float, unc: float | None) -> float | None:
        return float(dist / unc) if unc is not None and np.isfinite(unc) and unc > 0 else None

    for n in ("alpha", "beta", "gamma"):
        if n in params and np.isfinite(params[n]) and abs(math.degrees(params[n])) > max_angle_deg:
            issues.append({"message": f"{n} = {math.degrees(params[n]):.3g} deg exceeds {max_angle_deg:g} deg",
                           "kind": "angle", "parameter": n,
                           "excess_in_u": excess(abs(params[n]) - math.radians(max_angle_deg), u.get(n))})
    kz = params.get("Kz", 1.0)
    gains = {}
    for ax in "xyz":
        if f"K{ax}" in params:
            gains[ax] = params[f"K{ax}"]
        elif f"dK{ax}" in params:
            gains[ax] = 1.0 + params[f"dK{ax}"]
    for ax in "xy":
        if ax in gains and np.isfinite(gains[ax]):
            ratio = gains[ax] / kz
            if not gain_ratio[0] <= ratio <= gain_ratio[1]:
                name = f"K{ax}" if f"K{ax}" in params else f"dK{ax}"
                # u of the ratio: relative u of the two gains in quadrature (Kz fixed to 1 when estimated).
                ur = None
                if u.get(name) is not None:
                    rel = (u[name] / abs(gains[ax])) ** 2 + ((u.get("Kz") or 0.0) / abs(kz)) ** 2
                    ur = abs(ratio) * math.sqrt(rel)
                lim = gain_ratio[0] if ratio < gain_ratio[0] else gain_ratio[1]
                issues.append({"message": f"gain ratio K{ax}/Kz = {ratio:.4g} outside [{gain_ratio[0]:g}, "
                                          f"{gain_ratio[1]:g}]", "kind": "gain", "parameter": name,
                               "excess_in_u": excess(abs(ratio - lim), ur)})
    k_common = params.get("K", kz)
    for ax in "xyz":
        b = params.get(f"B{ax}")
        if max_offset is not None and b is not None and np.isfinite(b):
            full = abs(gains.get(ax, k_common)) * field
            if abs(b) > max_offset * full:
                issues.append({"message": f"offset B{ax} = {b:.4g} exceeds {max_offset:g} of the axis response to "
                                          f"the field ({full:.4g})", "kind": "offset", "parameter": f"B{ax}",
                               "excess_in_u": excess(abs(b) - max_offset * full, u.get(f"B{ax}"))})
    return issues


def plausibility(params: dict[str, float], field: float, *, max_angle_deg: float = 5.0,
                 gain_ratio: tuple[float, float] = (0.8, 1.25), max_offset: float | None = 0.5) -> list[str]:
    """Physical-range checks on fitted parameters (angles in rad): one message per value outside its range.

    Angle beyond ``max_angle_deg``, gain ratio (Kx/Kz, Ky/Kz, or 1+dK)
    outside ``gain_ratio``, offset larger than ``max_offset`` of the axis
    full response ``K F`` (None: offsets not judged, e.g. raw counts whose
    offsets hold the converter's zero).  Whether the data support such a
    value is decided by the caller (:func:`plausibility_checks` gives the
    distance in u; :func:`senscal.triaxial.calibrate` adds held-out evidence).
    """
    return [c["message"] for c in plausibility_checks(params, field, max_angle_deg=max_angle_deg,
                                                      gain_ratio=gain_ratio, max_offset=max_offset)]


def quantisation_step(h: np.ndarray, min_levels: int = 8) -> float | None:
    """The converter's step size, if the readings are visibly quantised.

    An axis is quantised when its distinct values are (to 1 % of the step)
    integer multiples of the smallest gap between them; floating-point data
    with real noise have gaps of every size.  Axes with fewer than
    ``min_levels`` distinct values say too little and are skipped.

    Returns
    -------
    float or None
        RMS of the axes' steps (sensor units), None when no axis is quantised.
    """
    steps = []
    for x in np.asarray(h, float):
        u = np.unique(x)
        if u.size < min_levels:
            continue
        d = np.diff(u)
        q = float(d.min())
        if not q > 0:
            continue
        k = d / q
        if np.all(np.abs(k - np.round(k)) < 0.01) and float(np.median(k)) < 1000:
            steps.append(q)
    return float(np.sqrt(np.mean(np.square(steps)))) if steps else None
