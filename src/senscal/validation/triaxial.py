"""Monte-Carlo coverage of ``senscal triaxial calibrate`` (automatic model choice).

Each scenario simulates a magnetometer with the simulator's default errors
(gains 1.03 / 0.98 / 1, angles 0.8 / -1.1 / 0.6 deg, offsets 300 / -200 /
150 nT, 20 nT white noise in a 50,000 nT field) turned through one kind of
motion, calibrates it with the field magnitude *estimated* (the default,
so gains are relative to Kz and the field is in Z-axis units) and the model
chosen automatically, and checks every number the result quotes against
the truth *of the model it was quoted in* at k = 2: a row per parameter
name holds the seeds that reported that parameter (non-null), whichever
model was chosen.  A parameter reported as null is not a quoted number;
a model that is not exact for the simulated sensor (``diagonal`` or
``offsets`` when the angles are not zero) is judged against the exact
values, so its bias counts as misses.  The row's note says how often the
expected model was chosen.

Scenarios: ``sphere`` (all directions), ``hemisphere`` (Z never negative),
``band-15deg`` (within +/-15 deg of the XY plane) and ``level-turn`` (72
headings of one level turn, the seed's protocol with more readings: the
planar model's in-plane parameters); and the seed's linearised model by
``--method linear`` with small errors (must cover) and with the default
3 % / 1 deg errors (the ``linearisation-error`` warning must fire).
"""

from __future__ import annotations

import math

import numpy as np

from senscal.simulate.triaxial import simulate_magnetometer
from senscal.diagnostics import has_warning
from senscal.triaxial import calibrate
from senscal.validation import CoverageRow, coverage_row

__all__ = ["SCENARIOS", "TIMED_RUNS", "TIME_WARNINGS", "run_sphere", "run_hemisphere", "run_band", "run_level_turn", "truth_full",
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


def _run(case: str, expect_model: str, names, sim_kw: dict, n_seeds: int, seed0: int,
         note: str) -> list[CoverageRow]:
    est: dict[str, list] = {}
    unc: dict[str, list] = {}
    tru: dict[str, list] = {}
    chosen = []
    for s in range(seed0, seed0 + n_seeds):
        rec, t = simulate_magnetometer(seed=s, **sim_kw)
        res = calibrate(rec.data())
        chosen.append(res.model)
        tv = truth_planar(t, sim_kw.get("inclination_deg", INCLINATION_DEG)) if res.model == "planar" else truth_full(t)
        for n, p in res.parameters.items():
            if p["value"] is None:
                continue  # null: not a quoted number (the reason is in the result)
            est.setdefault(n, []).append(p["value"])
            # A value without u is quoted without an interval: a miss.
            unc.setdefault(n, []).append(p["u"] if p["u"] is not None else math.nan)
            tru.setdefault(n, []).append(tv.get(n, math.nan))
    frac = sum(c == expect_model for c in chosen) / max(len(chosen), 1)
    others = sorted(set(chosen) - {expect_model})
    full_note = (f"{note}; {expect_model} chosen in {100 * frac:.0f} % of seeds"
                 + (f" (else {', '.join(others)})" if others else ""))
    order = list(names) + sorted(set(est) - set(names))
    return [coverage_row(JOB, case, n, est[n], unc[n], tru[n], note=full_note) for n in order if n in est]


def run_sphere(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings over all directions: the full model's 9 parameters."""
    return _run("sphere", "full", FULL_NAMES, {"motion": "sphere", "n": 300}, n_seeds, seed0,
                "300 directions over the sphere, white noise")


def run_hemisphere(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings with Z >= 0: the full model's 9 parameters."""
    return _run("hemisphere", "full", FULL_NAMES, {"motion": "hemisphere", "n": 300}, n_seeds, seed0,
                "300 directions over the upper hemisphere, white noise")


def run_band(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """300 readings within +/-15 deg of the XY plane: the full model's 9 parameters."""
    return _run("band-15deg", "full", FULL_NAMES, {"motion": "band", "n": 300, "band_deg": 15.0},
                n_seeds, seed0, "300 directions within +/-15 deg of the XY plane, white noise")


def run_level_turn(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """72 headings of one level turn: the planar model's 5 parameters."""
    return _run("level-turn", "planar", PLANAR_NAMES,
                {"motion": "planar", "n": 72, "inclination_deg": INCLINATION_DEG}, n_seeds, seed0,
                "72 headings of a level turn, white noise")


SMALL_ERRORS = {"gains": (1.002, 0.999, 1.0), "alpha_deg": 0.05, "beta_deg": -0.05, "gamma_deg": 0.03,
                "offsets": (30.0, -20.0, 15.0)}
LINEAR_NAMES = ("dKx", "dKy", "gamma", "alpha", "beta", "Bx", "By", "Bz", "field")


def _run_linear(case: str, errors: dict, expect: str, n_seeds: int, seed0: int, note: str) -> list[CoverageRow]:
    est = {n: [] for n in LINEAR_NAMES}
    unc = {n: [] for n in LINEAR_NAMES}
    tru = {n: [] for n in LINEAR_NAMES}
    warned = []
    for s in range(seed0, seed0 + n_seeds):
        rec, t = simulate_magnetometer(seed=s, motion="sphere", n=300, **errors)
        res = calibrate(rec.data(), method="linear")
        warned.append(has_warning(res.warnings, "linearisation-error"))
        tv = {**t["linear_weights"], "field": t["field"] * t["Kz"]}
        for n in LINEAR_NAMES:
            p = res.parameters.get(n) if res.model == "full" else None
            ok = p is not None and p["value"] is not None and p["u"] is not None
            est[n].append(p["value"] if ok else math.nan)
            unc[n].append(p["u"] if ok else math.nan)
            tru[n].append(tv[n])
    return [coverage_row(JOB, case, n, est[n], unc[n], tru[n], warned=warned, expect=expect, note=note)
            for n in LINEAR_NAMES]


def run_linear_small(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """``--method linear`` where the small-error model holds (0.2 % gains, 0.05 deg): must cover."""
    return _run_linear("linear-small-errors", SMALL_ERRORS, "cover", n_seeds, seed0,
                       "--method linear, 300 directions, errors 0.2 % / 0.05 deg / 30 nT: linearisation error << u")


def run_linear_default(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """``--method linear`` with the default errors (3 % gains, 1 deg): the linearisation error must be named."""
    return _run_linear("linear-3pct-errors", {}, "warn", n_seeds, seed0,
                       "--method linear, 300 directions, errors 3 % / 1 deg / 300 nT: second-order terms >> u, "
                       "named linearisation-error")


for _f in (run_sphere, run_hemisphere, run_band, run_level_turn, run_linear_small, run_linear_default):
    _f.full_seeds = 400  # type: ignore[attr-defined]


# -- slow changes during the session (issue 26 item 1) -----------------------------------------------------
# 300 orientations over the sphere, either in random order or as a systematic tumble (Z axis from up to
# down), with an offset drift over the session or a field step halfway.  In random order the drift and the
# step are found and modelled (the parameters must cover); in a tumble the orientations follow time, the data
# cannot tell a drift or a step from the angles, gains, Bz and the field, and that must be named
# (time-confounded, or inconsistent-blocks when the halves of the session disagree): every row of a tumble
# case, the terms' values included, expects the warning.
TIME_WARNINGS = ("time-confounded", "inconsistent-blocks")
TERM_TRUTH = {f"dB{a}": (lambda t, k=k: t["drift_linear"][k] if t["drift"] is not None else 0.0)
              for k, a in enumerate("xyz")}
TERM_TRUTH["dF"] = lambda t: t["field_step"] * t["Kz"]


def _run_timed(case: str, sim_kw: dict, expect: str, n_seeds: int, seed0: int, note: str,
               term_rows: tuple[str, ...] = ()) -> list[CoverageRow]:
    names = FULL_NAMES + tuple(TERM_TRUTH)
    est: dict[str, list] = {n: [] for n in names}
    unc: dict[str, list] = {n: [] for n in names}
    tru: dict[str, list] = {n: [] for n in names}
    warned, adopted = [], []
    for s in range(seed0, seed0 + n_seeds):
        rec, t = simulate_magnetometer(seed=s, motion="sphere", n=300, **sim_kw)
        res = calibrate(rec.data())
        warned.append(any(has_warning(res.warnings, w) for w in TIME_WARNINGS))
        tt = res.time_terms or {}
        terms = tt.get("terms", {})
        adopted.append(bool(terms))
        tv = truth_full(t)
        for n in FULL_NAMES:
            p = res.parameters.get(n)
            ok = p is not None and p["value"] is not None and p["u"] is not None
            est[n].append(p["value"] if ok else math.nan)  # a null in a case that must cover is a miss
            unc[n].append(p["u"] if ok else math.nan)
            tru[n].append(tv[n])
        for n, truth in TERM_TRUTH.items():
            # A term's own row only where the scenario has it at a size the test finds in nearly every seed
            # (term_rows): a term adopted on weak evidence was selected for looking large, so its interval
            # misses by construction (post-selection); the parameters' rows judge those seeds.
            if n in terms and n in term_rows:
                est[n].append(terms[n]["value"])
                unc[n].append(terms[n]["u"])
                tru[n].append(truth(t))
    full_note = f"{note}; a time term modelled in {100 * sum(adopted) / max(len(adopted), 1):.0f} % of seeds"
    return [coverage_row(JOB, case, n, est[n], unc[n], tru[n], warned=warned, expect=expect, note=full_note)
            for n in names if est[n]]


def _timed(case, sim_kw, expect, note, ci_seeds, term_rows=()):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        return _run_timed(case, sim_kw, expect, n_seeds, seed0, note, term_rows)

    run.__doc__ = f"{note} (expect: {expect})."
    run.full_seeds = 200  # type: ignore[attr-defined]
    run.ci_seeds = ci_seeds  # type: ignore[attr-defined]
    return run


DRIFT_10 = (10.0, -7.0, 8.0)
DRIFT_30 = (30.0, -20.0, 25.0)
DRIFT_TERMS = ("dBx", "dBy", "dBz")
TIMED = {
    "tumble-white": ({"order": "tumble"}, "warn",
                     "tumble Z up -> Z down, no drift: the design alone cannot tell a drift from the parameters", 5),
    "tumble-drift-10nT": ({"order": "tumble", "drift": DRIFT_10}, "warn",
                          "tumble Z up -> Z down, offsets drift (10, -7, 8) nT over the session", 5, DRIFT_TERMS),
    "tumble-drift-30nT": ({"order": "tumble", "drift": DRIFT_30}, "warn",
                          "tumble Z up -> Z down, offsets drift (30, -20, 25) nT over the session", 5, DRIFT_TERMS),
    "tumble-step-3nT": ({"order": "tumble", "field_step": 3.0}, "warn",
                        "tumble Z up -> Z down, the field steps by 3 nT halfway", 5, ("dF",)),
    "tumble-step-100nT": ({"order": "tumble", "field_step": 100.0}, "warn",
                          "tumble Z up -> Z down, the field steps by 100 nT halfway", 5, ("dF",)),
    "random-drift-30nT": ({"drift": DRIFT_30}, "cover",
                          "random order, offsets drift (30, -20, 25) nT over the session", 8, DRIFT_TERMS),
    "random-warmup-30nT": ({"drift": DRIFT_30, "drift_shape": "warmup"}, "cover",
                           "random order, offsets settle by (30, -20, 25) nT like a warm-up (1 - exp(-3 s))", 8,
                           DRIFT_TERMS),
    "random-step-100nT": ({"field_step": 100.0}, "cover", "random order, the field steps by 100 nT halfway", 8,
                          ("dF",)),
    # A 3 nT step is about 1.3 u of dF: found in ~10 % of seeds, and then because the noise made it look large,
    # so dF has no row here (post-selection); the parameters must cover either way.
    "random-step-3nT": ({"field_step": 3.0}, "cover", "random order, the field steps by 3 nT halfway", 8),
}
TIMED_RUNS = {k: _timed(k, *v) for k, v in TIMED.items()}

SCENARIOS = {"sphere": run_sphere, "hemisphere": run_hemisphere, "band-15deg": run_band,
             "level-turn": run_level_turn, "linear-small-errors": run_linear_small,
             "linear-3pct-errors": run_linear_default, **TIMED_RUNS}
