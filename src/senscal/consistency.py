"""Internal consistency of a result: refit on blocks of the record and compare with the stated u.

Any job whose record can be cut into pieces that each determine the quoted
quantities can check itself: fit every block, then ask whether the block
estimates agree within their own stated uncertainties.  Departures nobody
listed -- a drift, a step, noise below 1/T, an effect ordered in time, a
regressor that changes meaning over the record -- make the blocks disagree
more than their u allows, and the check names them (``inconsistent-blocks``)
without knowing what they are.

The test is the chi-square (Birge ratio) test of a weighted mean: with K
blocks and standard uncertainties ``u_b``, ``chi2 = sum_b (x_b - xbar)^2 /
u_b^2`` follows chi-square with ``K - 1`` degrees of freedom when every ``u_b``
is right; ``R_B = sqrt(chi2 / (K - 1))`` is the Birge ratio.  Each quantity
is tested at level ``alpha / Q`` (Bonferroni over the ``Q`` quantities), so the
whole check has a false-alarm rate of at most ``alpha`` (1 % by default).

Examples
--------
>>> import numpy as np
>>> from senscal.consistency import block_consistency, split_blocks
>>> rng = np.random.default_rng(1)
>>> y = 0.3 + rng.normal(0, 0.05, 4000)
>>> def mean_fit(idx):
...     b = y[idx]
...     return {"offset": (b.mean(), b.std(ddof=1) / np.sqrt(b.size))}
>>> res = block_consistency(mean_fit, split_blocks(y.size, 4))
>>> res.consistent
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from senscal._result import ResultMixin, to_jsonable
from senscal.diagnostics import named

__all__ = ["BlockConsistency", "QuantityConsistency", "block_consistency", "split_blocks", "ALPHA"]

#: False-alarm probability of the whole check (all quantities together) on a record that meets its model.
ALPHA = 0.01


@dataclass(frozen=True)
class QuantityConsistency(ResultMixin):
    """The chi-square test of one quantity over the blocks.

    Attributes
    ----------
    name : str
    values, u : tuple of float
        Block estimates and their standard uncertainties (unit of the quantity).
    weighted_mean : float
    chi2 : float
        ``sum (x_b - xbar)^2 / u_b^2``.
    dof : int
        ``K - 1``.
    birge_ratio : float
        ``sqrt(chi2 / dof)`` (1 when the u are right).
    limit : float
        Quantile the statistic was compared with (level ``alpha / Q``):
        chi-square with ``dof``, or ``dof`` times F(dof, nu) when the blocks'
        u have ``nu`` degrees of freedom.
    p_value : float
        Upper-tail probability of ``chi2``.
    consistent : bool
        ``chi2 <= limit``.
    """

    name: str
    values: tuple[float, ...]
    u: tuple[float, ...]
    weighted_mean: float
    chi2: float
    dof: int
    birge_ratio: float
    limit: float
    p_value: float
    consistent: bool


@dataclass(frozen=True)
class BlockConsistency(ResultMixin):
    """Block-refit consistency of a result's quantities.

    Attributes
    ----------
    n_blocks : int
        Blocks that gave an estimate.
    quantities : tuple of QuantityConsistency
    alpha : float
        Overall false-alarm probability.
    """

    n_blocks: int
    quantities: tuple[QuantityConsistency, ...]
    alpha: float = ALPHA

    @property
    def consistent(self) -> bool:
        """True when every quantity passed its test."""
        return all(q.consistent for q in self.quantities)

    @property
    def failing(self) -> tuple[QuantityConsistency, ...]:
        """The quantities that failed."""
        return tuple(q for q in self.quantities if not q.consistent)

    def warning(self, where: str = "") -> str | None:
        """The ``inconsistent-blocks`` named warning, or None when consistent.

        Parameters
        ----------
        where : str
            Prefix naming the channel/point (e.g. ``"channel 'ch1': "``).
        """
        bad = self.failing
        if not bad:
            return None
        parts = ", ".join(f"{q.name} (Birge ratio {q.birge_ratio:.2g}, p = {q.p_value:.1g})" for q in bad)
        return named("inconsistent-blocks", (
            f"{where}refitted on {self.n_blocks} consecutive blocks of the record, {parts} scatter"
            f"{'s' if len(bad) == 1 else ''} more than the blocks' own uncertainties allow: something changes "
            f"over the record (drift, a step, noise below 1/T, a disturbance) that the stated u does not "
            f"include; look at the blocks' values, shorten or repeat the measurement"))

    def to_dict(self) -> dict[str, Any]:
        return {"n_blocks": self.n_blocks, "alpha": self.alpha, "consistent": self.consistent,
                "quantities": {q.name: {"values": to_jsonable(q.values), "u": to_jsonable(q.u),
                                        "birge_ratio": to_jsonable(q.birge_ratio), "chi2": to_jsonable(q.chi2),
                                        "dof": q.dof, "limit": to_jsonable(q.limit),
                                        "p_value": to_jsonable(q.p_value), "consistent": q.consistent}
                               for q in self.quantities}}


def split_blocks(n: int, k: int) -> list[np.ndarray]:
    """Indices of ``k`` consecutive, nearly equal blocks of ``n`` samples."""
    if k < 2 or n < k:
        raise ValueError(f"cannot split {n} samples into {k} blocks")
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return [np.arange(edges[i], edges[i + 1]) for i in range(k)]


def block_consistency(fit: Callable[[np.ndarray], Mapping[str, tuple[float, float]]],
                      blocks: Sequence[np.ndarray], *, alpha: float = ALPHA,
                      circular: Sequence[str] = ()) -> BlockConsistency:
    """Fit every block and test the estimates of each quantity against their u.

    Parameters
    ----------
    fit : callable
        ``fit(indices) -> {name: (value, standard_u)}`` or ``{name: (value,
        standard_u, dof)}`` for the samples at ``indices``; ``dof`` is the
        degrees of freedom of ``u`` (u estimated from few residuals scatters:
        the test then compares ``chi2 / (K - 1)`` with an F quantile with the
        smallest ``dof``, not with a chi-square one).  It may raise :class:`senscal.errors.SenscalError` for
        a block it cannot fit; that block is left out.  Values must be
        comparable between blocks (the same reference time for a phase).
    blocks : sequence of ndarray
        Sample indices of each block (e.g. :func:`split_blocks`).
    alpha : float
        Overall false-alarm probability (Bonferroni over the quantities).
    circular : sequence of str
        Quantities that are angles in rad (differences wrapped to (-pi, pi]).

    Returns
    -------
    BlockConsistency
        With fewer than two usable blocks, no quantities (and consistent).
    """
    # scipy.special's distribution functions: microseconds a call, where scipy.stats takes a hundred.
    from scipy.special import chdtrc, chdtri, fdtrc, fdtri

    from senscal.errors import SenscalError

    per: dict[str, list[tuple[float, float, float]]] = {}
    n_ok = 0
    for idx in blocks:
        try:
            out = fit(np.asarray(idx))
        except SenscalError:
            continue
        n_ok += 1
        for name, vu in out.items():
            dof = float(vu[2]) if len(vu) > 2 and vu[2] is not None else math.inf
            per.setdefault(name, []).append((float(vu[0]), float(vu[1]), dof))
    names = [nm for nm, vals in per.items() if len(vals) >= 2]
    q = max(len(names), 1)
    res = []
    for nm in names:
        v = np.array([a for a, _, _ in per[nm]])
        u = np.array([b for _, b, _ in per[nm]])
        nu = np.array([c for _, _, c in per[nm]])
        good = np.isfinite(v) & np.isfinite(u) & (u > 0)
        v, u, nu = v[good], u[good], nu[good]
        if v.size < 2:
            continue
        if nm in circular:
            # Unwrap about the first block so that a phase near +/-pi is not split.
            v = v[0] + np.angle(np.exp(1j * (v - v[0])))
        w = 1.0 / u**2
        mean = float(np.sum(w * v) / np.sum(w))
        c2 = float(np.sum(w * (v - mean) ** 2))
        dof = int(v.size - 1)
        nu_min = float(np.min(nu))
        if math.isfinite(nu_min) and nu_min > 0:
            # u^2 from nu dof is chi2_nu / nu: the ratio of the scatter to it is F(K-1, nu).
            lim = float(dof * fdtri(dof, nu_min, 1.0 - alpha / q))
            pv = float(fdtrc(dof, nu_min, c2 / dof))
        else:
            lim = float(chdtri(dof, alpha / q))
            pv = float(chdtrc(dof, c2))
        res.append(QuantityConsistency(nm, tuple(v.tolist()), tuple(u.tolist()), mean, c2, dof,
                                       math.sqrt(c2 / dof), lim, pv, c2 <= lim))
    return BlockConsistency(n_ok, tuple(res), alpha)
