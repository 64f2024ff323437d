"""Monte-Carlo coverage of reported uncertainties against simulated truth.

Each job has a module here (``senscal.validation.sinefit``, ...) whose
``SCENARIOS`` maps a scenario name to a function ``run(n_seeds, seed0)`` that
simulates ``n_seeds`` recordings with known truth (white noise or a named
departure from the model), runs the job and returns :class:`CoverageRow`
objects, one per reported quantity.  The tests run every scenario with a
number of seeds that CI can afford (:func:`mc_seeds`) and check it with
:func:`check_coverage`; ``benchmarks/bench_coverage.py`` runs all of them with
the full number and prints one table.

A scenario whose departure the job *warns* about instead of covering reports
``warned`` = fraction of seeds that raised the named warning; such a row
passes when the warning fires (>= 95 % of seeds), whatever the coverage.
"""

from __future__ import annotations

import importlib
import math
import os
import pkgutil
from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from senscal._result import ResultMixin

__all__ = [
    "CoverageRow", "coverage_row", "wilson_interval", "check_coverage", "coverage_ok",
    "mc_seeds", "scenarios", "TARGET", "TOLERANCE",
]

TARGET = 0.95      # k = 2 for a normal estimate
TOLERANCE = 0.02   # the project's rule: 95 +/- 2 %
_Z_CONF = 3.29     # two-sided 99.9 %: the test fails only when the miss is certain


def wilson_interval(hits: int, n: int, z: float = _Z_CONF) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    Parameters
    ----------
    hits, n : int
        Successes and trials.
    z : float
        Normal quantile (3.29: two-sided 99.9 %).

    Returns
    -------
    (low, high) : tuple of float
    """
    if n <= 0:
        return 0.0, 1.0
    p = hits / n
    den = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class CoverageRow(ResultMixin):
    """Coverage of one reported quantity over Monte-Carlo seeds.

    Attributes
    ----------
    job, case, quantity : str
        Which job, which scenario (``white``, ``ar1-0.9``, ...), which number.
    n : int
        Seeds that produced a result.
    coverage : float
        Fraction of seeds with ``|estimate - truth| <= k u`` (k = 2).
    z_spread : float
        Standard deviation of ``(estimate - truth) / u`` (1 when u is right).
    warned : float
        Fraction of seeds that raised the scenario's named warning (NaN when
        the scenario expects no warning).
    expect : str
        ``"cover"`` (the interval must cover 95 +/- 2 %) or ``"warn"`` (the
        departure must be named in a warning).
    note : str
        What the scenario departs in, in words.
    """

    job: str
    case: str
    quantity: str
    n: int
    coverage: float
    z_spread: float
    warned: float = float("nan")
    expect: str = "cover"
    note: str = ""

    @property
    def interval(self) -> tuple[float, float]:
        """99.9 % Wilson interval of the coverage."""
        return wilson_interval(int(round(self.coverage * self.n)), self.n)

    @property
    def ok(self) -> bool:
        """True when the row meets the rule (see :func:`coverage_ok`)."""
        return coverage_ok(self)


def coverage_row(job: str, case: str, quantity: str, estimate, u, truth, *, k: float = 2.0,
                 warned: Sequence[bool] | None = None, expect: str = "cover", note: str = "") -> CoverageRow:
    """Build a :class:`CoverageRow` from per-seed estimates, u and truth.

    Parameters
    ----------
    estimate, u, truth : array_like
        One value per seed (truth may be a scalar).  Seeds with a non-finite
        estimate or u count as misses (a result without a usable u does not
        cover).
    k : float
        Coverage factor.
    warned : sequence of bool, optional
        Per seed: did the scenario's named warning fire.
    """
    est = np.asarray(estimate, dtype=float).ravel()
    uu = np.asarray(u, dtype=float).ravel()
    tr = np.broadcast_to(np.asarray(truth, dtype=float), est.shape).ravel()
    z = (est - tr) / uu
    good = np.isfinite(z)
    hits = int(np.sum(np.abs(z[good]) <= k))
    n = est.size
    spread = float(np.std(z[good], ddof=1)) if good.sum() > 1 else float("nan")
    w = float(np.mean(np.asarray(warned, dtype=bool))) if warned is not None and len(warned) else float("nan")
    return CoverageRow(job, case, quantity, int(n), hits / n if n else float("nan"), spread, w, expect, note)


def coverage_ok(row: CoverageRow, *, target: float = TARGET, tol: float = TOLERANCE) -> bool:
    """Does a row meet the rule, given its number of seeds?

    ``expect="cover"``: the 99.9 % Wilson interval of the observed coverage
    overlaps ``target +/- tol`` (so a test with few seeds fails only when the
    miss is statistically certain; with 400 seeds a coverage of 90 % fails).
    ``expect="warn"``: the named warning fired in at least 95 % of seeds.
    """
    if row.expect == "warn":
        return bool(np.isfinite(row.warned) and row.warned >= 0.95)
    lo, hi = row.interval
    return hi >= target - tol and lo <= target + tol


def check_coverage(rows: Iterable[CoverageRow], **kw) -> None:
    """Raise AssertionError naming every row that breaks the rule."""
    rows = list(rows)
    bad = [r for r in rows if not coverage_ok(r, **kw)]
    if bad:
        lines = [f"{r.job}/{r.case}/{r.quantity}: coverage {100 * r.coverage:.1f}% "
                 f"(99.9% CI {100 * r.interval[0]:.1f}-{100 * r.interval[1]:.1f}%, n={r.n}), "
                 f"z spread {r.z_spread:.2f}, warned {r.warned:.2f}, expect {r.expect}" for r in bad]
        raise AssertionError("coverage rule broken:\n" + "\n".join(lines))


def mc_seeds(full: int, ci: int | None = None) -> int:
    """Number of Monte-Carlo seeds for a coverage test.

    ``SENSCAL_MC=full`` (the benchmark, or a thorough local run) gives
    ``full``; otherwise ``ci`` (default ``full // 2``, at least 100), which
    keeps the suite inside CI's budget while still failing a coverage of
    90 % instead of 95 % with high probability for fast fits.
    """
    if os.environ.get("SENSCAL_MC", "").lower() == "full":
        return int(full)
    return int(ci if ci is not None else max(100, full // 2))


def scenarios() -> dict[str, Mapping[str, Callable[..., list[CoverageRow]]]]:
    """All scenarios of all jobs: ``{module: {scenario: run}}``."""
    out: dict[str, Mapping[str, Callable[..., list[CoverageRow]]]] = {}
    for info in pkgutil.iter_modules(__path__):  # type: ignore[name-defined]
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        sc = getattr(mod, "SCENARIOS", None)
        if sc:
            out[info.name] = sc
    return out
