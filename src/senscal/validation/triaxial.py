"""Monte-Carlo coverage of ``senscal triaxial calibrate`` (automatic model choice).

Each scenario simulates a magnetometer with the simulator's default errors
(gains 1.03 / 0.98 / 1, angles 0.8 / -1.1 / 0.6 deg, offsets 300 / -200 /
150 nT, 20 nT white noise in a 50,000 nT field) turned through one kind of
motion, calibrates it with the field magnitude *estimated* (the default,
so gains are relative to Kz and the field is in Z-axis units) and the model
chosen automatically, and checks every parameter of the expected model
against the truth at k = 2.  A seed where the automatic choice is another
model, or where a parameter is reported as null, counts as a miss for
that parameter: a user would have quoted the other model's numbers.

Scenarios: ``sphere`` (all directions), ``hemisphere`` (Z never negative),
``band-15deg`` (within +/-15 deg of the XY plane) and ``level-turn`` (72
headings of one level turn, the seed's protocol with more readings: the
planar model's in-plane parameters).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.simulate.triaxial import simulate_magnetometer
from senscal.triaxial import calibrate
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "run_sphere", "run_hemisphere", "run_band", "run_level_turn", "truth_full",
           "truth_planar"]

JOB = "triaxial"
FULL_NAMES = ("Kx", "Ky", "alpha", "beta", "gamma", "Bx", "By", "Bz", "field")
PLANAR_NAMES = ("Kx", "gamma", "Bx", "By", "plane_field")
INCLINATION_DEG = 60.0


def truth_full(t: dict) -> dict[str, float]:
    """The full model's parameters with the field estimated (gains relative to Kz, field in Z units)."""
    kz = t["Kz"]
    return {"Kx": t["Kx"] / kz, "Ky": t["Ky"] / kz, "alpha": math.radians(t["alpha_deg"]),
            "beta": math.radians(t["beta_deg"]), "gamma": math.radians(t["gamma_deg"]), "Bx": t["Bx"],
            "By": t["By"], "Bz": t["Bz"], "field": t["field"] * kz}


def truth_planar(t: dict, inclination_deg: float = INCLINATION_DEG) -> dict[str, float]:
    """The planar (X, Y) model's parameters of a level turn.

    The in-plane block of ``M`` divided by ``Ky cos(beta)`` (the model fixes
    that element to 1), and offsets that include the constant vertical field
    leaking through alpha and beta.
    """
    a, b, g = (math.radians(t[f"{n}_deg"]) for n in ("alpha", "beta", "gamma"))
    hz = t["field"] * math.sin(math.radians(inclination_deg))
    hp = t["field"] * math.cos(math.radians(inclination_deg))
    m00, m01 = t["Kx"] * math.cos(a) * math.cos(g), t["Kx"] * math.sin(g)
    m11 = t["Ky"] * math.cos(b)
    return {"Kx": math.hypot(m00, m01) / m11, "gamma": math.atan2(m01, m00),
            "Bx": t["Bx"] + t["Kx"] * math.sin(a) * math.cos(g) * hz, "By": t["By"] + t["Ky"] * math.sin(b) * hz,
            "plane_field": m11 * hp}


def _run(case: str, expect_model: str, names, sim_kw: dict, truth_fn, n_seeds: int, seed0: int,
         note: str) -> list[CoverageRow]:
    est = {n: [] for n in names}
    unc = {n: [] for n in names}
    tru = {n: [] for n in names}
    for s in range(seed0, seed0 + n_seeds):
        rec, t = simulate_magnetometer(seed=s, **sim_kw)
        res = calibrate(rec.data())
        tv = truth_fn(t)
        for n in names:
            p = res.parameters.get(n) if res.model == expect_model else None
            ok = p is not None and p["value"] is not None and p["u"] is not None
            est[n].append(p["value"] if ok else math.nan)
            unc[n].append(p["u"] if ok else math.nan)
            tru[n].append(tv[n])
    return [coverage_row(JOB, case, n, est[n], unc[n], tru[n], note=note) for n in names]


def run_sphere(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings over all directions: the full model's 9 parameters."""
    return _run("sphere", "full", FULL_NAMES, {"motion": "sphere", "n": 300}, truth_full, n_seeds, seed0,
                "300 directions over the sphere, white noise")


def run_hemisphere(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings with Z >= 0: the full model's 9 parameters."""
    return _run("hemisphere", "full", FULL_NAMES, {"motion": "hemisphere", "n": 300}, truth_full, n_seeds,
                seed0, "300 directions over the upper hemisphere, white noise")


def run_band(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings within +/-15 deg of the XY plane: the full model's 9 parameters."""
    return _run("band-15deg", "full", FULL_NAMES, {"motion": "band", "n": 300, "band_deg": 15.0}, truth_full,
                n_seeds, seed0, "300 directions within +/-15 deg of the XY plane, white noise")


def run_level_turn(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """72 headings of one level turn: the planar model's 5 parameters."""
    return _run("level-turn", "planar", PLANAR_NAMES,
                {"motion": "planar", "n": 72, "inclination_deg": INCLINATION_DEG}, truth_planar, n_seeds, seed0,
                "72 headings of a level turn, white noise")


for _f in (run_sphere, run_hemisphere, run_band, run_level_turn):
    _f.full_seeds = 400  # type: ignore[attr-defined]

SCENARIOS = {"sphere": run_sphere, "hemisphere": run_hemisphere, "band-15deg": run_band,
             "level-turn": run_level_turn}
