"""Monte-Carlo coverage of the vibration jobs: velocity, response, repeats, linearity.

Each scenario simulates rigs with known truth (``senscal.simulate.vibration``,
white noise or one named departure built into the simulator), runs the same
functions the CLI runs and returns one :class:`~senscal.validation.CoverageRow`
per reported quantity.  Per-point quantities pool every frequency point of
every seed (independent records), so ``n`` counts points; means count seeds.

Departures:

* ``encoder-zero-5deg``: the encoder reads the turntable angle 5 deg off the
  field direction (``simulate_centrifuge(encoder_zero_deg=5)``); without an
  entered or measured phi_0 the phase delay must carry
  ``phase-reference-unknown``; with one it must cover.
* ``remount-0.1%``: the sensitivity changes by 0.1 % (standard deviation)
  from record to record (``sensitivity_scatter``): means must cover (type A
  is the spread with Student k); ``excess-scatter`` is reported as the
  fraction of seeds in which the chi-square test saw it.
* ``input-scatter``: each input level is off at random (``input_scatter``):
  0.1 % declared in ``u_input`` (must cover), or 0.5 % not declared (must
  say ``linearity-excess-scatter``; with five levels the test against a
  cubic has one degree of freedom, so smaller undeclared scatter can pass
  unseen: declare it).
* ``cubic-2e-6``: a 0.2 % cubic nonlinearity: the linearity is resolved and
  must cover.
* ``encoder-N-lines``: the angle comes from an encoder with N counts per
  revolution read as a counter (``simulate_centrifuge(encoder_lines=N)``,
  issue 25 item 7): the steps are an error in the regressor.  The step is
  detected in the readings (not declared), the fit uses the constant-speed
  line through them, and what the steps leave is the budget component
  ``encoder step``: S, S/S0 and the phase delay must cover.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import has_warning
from senscal.simulate.vibration import simulate_centrifuge, simulate_hydraulic
from senscal.validation import CoverageRow, coverage_row
from senscal.vibration import (amplitude_linearity, apply_phase_reference, combine_repeats, phase_reference_run,
                               response_point, velocity_calibration, velocity_point)

__all__ = ["SCENARIOS"]

JOB = "vibration"
# Hydraulic rig: three points of about 2 s at 1 kHz (four-parameter fits are the
# slow part) keep a seed near 0.1 s on a quiet core.
_HYD_FREQS = (2.0, 3.5, 5.5)
# Double centrifuge: the seed's 1, 5, 10 Hz (0.1 Hz needs 34 s per record).
_CF_FREQS = (1.0, 5.0, 10.0)
_CF_DURATION = 10.0
_A0 = 100.0
_S0 = 0.05
_LEVELS = (20.0, 40.0, 60.0, 80.0, 100.0)


def _velocity(case: str, scatter: float, n_seeds: int, seed0: int) -> list[CoverageRow]:
    est_pt, u_pt, tr_pt, ph, u_ph, tr_ph = [], [], [], [], [], []
    mean, u_mean, warned = [], [], []
    truth_mean = None
    for seed in range(seed0, seed0 + n_seeds):
        recs, truth = simulate_hydraulic(frequencies=_HYD_FREQS, periods=4.3, min_duration=2.0, sensitivity_scatter=scatter,
                                         seed=seed)
        pts = [velocity_point(r["position"], r["velocity"], r.time) for r in recs]
        cal = velocity_calibration(pts)
        for p, t in zip(pts, truth["points"]):
            est_pt.append(p.sensitivity)
            u_pt.append(p.u_sensitivity)
            tr_pt.append(t["sensitivity"])
            ph.append(math.degrees(p.phase))
            u_ph.append(math.degrees(p.u_phase))
            tr_ph.append(t["phase_deg"])
        k = cal.budget.coverage_factor / 2.0  # rows test |e| <= 2 u: fold the stated k into u
        mean.append(cal.sensitivity)
        u_mean.append(k * cal.u_sensitivity)
        warned.append(has_warning(cal.warnings, "excess-scatter"))
        truth_mean = truth["sensitivity"]
    note = "white noise" if not scatter else f"sensitivity varies {100 * scatter:g} % between records"
    w = warned if scatter else None
    return [coverage_row(JOB, case, "velocity S (point)", est_pt, u_pt, tr_pt, note=note),
            coverage_row(JOB, case, "velocity phase (point)", ph, u_ph, tr_ph, note=note),
            coverage_row(JOB, case, "velocity mean S (k stated)", mean, u_mean, truth_mean, warned=w, note=note)]


def run_velocity_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Hydraulic rig, white noise: point S, point phase, mean S (400 seeds, 3 points each)."""
    return _velocity("velocity-white", 0.0, n_seeds, seed0)


def run_velocity_scatter(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Hydraulic rig, sensitivity 0.1 % different in each record: the mean's u from the spread (Student k)."""
    return _velocity("velocity-remount-0.1%", 1e-3, n_seeds, seed0)


run_velocity_white.full_seeds = 400
run_velocity_scatter.full_seeds = 400


def _velocity_reference(case: str, name: str, n_seeds: int, seed0: int, **departure) -> list[CoverageRow]:
    """A reference channel that cannot be what it claims: the point S misses its truth, and ``name`` must
    be named in >= 95 % of seeds (a record counts as named when any of its points is)."""
    est, u, tr, warned = [], [], [], []
    for seed in range(seed0, seed0 + n_seeds):
        recs, truth = simulate_hydraulic(frequencies=_HYD_FREQS, periods=4.3, min_duration=2.0, seed=seed,
                                         **departure)
        pts = [velocity_point(r["position"], r["velocity"], r.time) for r in recs]
        est += [p.sensitivity for p in pts]
        u += [p.u_sensitivity for p in pts]
        tr += [t["sensitivity"] for t in truth["points"]]
        warned.append(all(has_warning(p.warnings, name) for p in pts))
    note = ", ".join(f"{k}={v}" for k, v in departure.items())
    return [coverage_row(JOB, case, "velocity S (point)", est, u, tr, warned=warned, expect="warn", note=note)]


def run_velocity_swapped(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Position and velocity columns swapped: every point must name velocity-not-derivative."""
    return _velocity_reference("velocity-swapped-channels", "velocity-not-derivative", n_seeds, seed0,
                               swap_channels=True)


def run_velocity_position_mm(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Position in mm under a bare header (read as m): every point must name position-amplitude-implausible."""
    return _velocity_reference("velocity-position-mm-as-m", "position-amplitude-implausible", n_seeds, seed0,
                               position_scale=1e3)


run_velocity_swapped.full_seeds = 200
run_velocity_position_mm.full_seeds = 200


def _response(case: str, n_seeds: int, seed0: int, *, encoder_zero: float, phase: str,
              encoder_lines: int = 0) -> list[CoverageRow]:
    """phase: 'entered' (phi_0 known to u = 0.001 deg), 'none' (nothing) or 'run' (a start-up run).

    The points of one seed share phi_0 (entered or measured once), so their
    phase-delay errors are partly correlated; u_entered is kept near the
    fits' u so the pooled rows still hold about 3 independent samples per seed.
    """
    s, us, ts, r, ur, tr, d, ud, td, warned = ([] for _ in range(10))
    u_entered = math.radians(0.001)
    for seed in range(seed0, seed0 + n_seeds):
        recs, truth = simulate_centrifuge(frequencies=_CF_FREQS, min_duration=_CF_DURATION,
                                          encoder_zero_deg=encoder_zero, encoder_lines=encoder_lines, seed=seed)
        rng = np.random.default_rng(10_000_000 + seed)
        phi0 = None
        if phase == "entered":
            # the operator's phi_0 is itself a measurement with its stated u
            phi0 = math.radians(truth["initial_phase_deg"]) + u_entered * rng.standard_normal()
        pts = [response_point(rec["output"], rec.time, input_amplitude=_A0, angle_deg=rec["angle"],
                              static_sensitivity=_S0, initial_phase=phi0,
                              u_input_phase=u_entered if phi0 is not None else 0.0, source=f"rec{i}")
               for i, rec in enumerate(recs)]
        if phase == "run":
            # the paper's start-up test: a slow run before the response points
            rr, _ = simulate_centrifuge(frequencies=(0.25,), min_duration=_CF_DURATION,
                                        encoder_zero_deg=encoder_zero, encoder_lines=encoder_lines,
                                        seed=20_000_000 + seed)
            ref = phase_reference_run(rr[0]["output"], rr[0].time, rr[0]["angle"], source="startup")
            pts = list(apply_phase_reference(pts, ref))
        for p, t in zip(pts, truth["points"]):
            s.append(p.sensitivity), us.append(p.u_sensitivity), ts.append(t["sensitivity"])
            r.append(p.normalized_sensitivity), ur.append(p.u_normalized_sensitivity)
            tr.append(t["normalized_sensitivity"])
            d.append(math.degrees(p.phase_delay)), ud.append(math.degrees(p.u_phase_delay))
            td.append(t["phase_delay_deg"])
            warned.append(has_warning(p.warnings, "phase-reference-unknown"))
    note = {"entered": "phi_0 entered (u 0.001 deg)", "none": "phi_0 neither entered nor measured",
            "run": "phi_0 from a 0.25 Hz start-up run"}[phase]
    note = (f"encoder zero {encoder_zero:g} deg off; " if encoder_zero else "white noise; ") + note
    if encoder_lines:
        note = f"{encoder_lines}-count encoder (step detected); " + note
    expect = "warn" if phase == "none" else "cover"
    return [coverage_row(JOB, case, "response S", s, us, ts, note=note),
            coverage_row(JOB, case, "response S/S0", r, ur, tr, note=note),
            coverage_row(JOB, case, "response phase delay", d, ud, td, warned=warned, expect=expect, note=note)]


def run_response_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Double centrifuge, white noise, phi_0 entered: S, S/S0, phase delay (1, 5, 10 Hz; 400 seeds)."""
    return _response("response-white", n_seeds, seed0, encoder_zero=0.0, phase="entered")


def run_response_encoder_unknown(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Encoder zero 5 deg off and no phi_0: the phase delay must carry phase-reference-unknown."""
    return _response("response-encoder-zero-5deg", n_seeds, seed0, encoder_zero=5.0, phase="none")


def run_response_encoder_entered(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Encoder zero 5 deg off, phi_0 = 95 deg entered with u = 0.001 deg: the phase delay covers."""
    return _response("response-encoder-zero-5deg+entered", n_seeds, seed0, encoder_zero=5.0, phase="entered")


def run_response_encoder_run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Encoder zero 5 deg off, phi_0 from a 0.25 Hz start-up run (its own delay extrapolated): covers."""
    return _response("response-encoder-zero-5deg+reference-run", n_seeds, seed0, encoder_zero=5.0, phase="run")


for _f in (run_response_white, run_response_encoder_unknown, run_response_encoder_entered, run_response_encoder_run):
    _f.full_seeds = 400


def _encoder_lines_scenario(lines: int, phase: str):
    def run(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
        return _response(f"response-encoder-{lines}-lines" + ("+reference-run" if phase == "run" else ""),
                         n_seeds, seed0, encoder_zero=0.0, phase=phase, encoder_lines=lines)

    run.__doc__ = (f"{lines}-count turntable encoder (issue 25 item 7), phi_0 "
                   + ("from a start-up run with the same encoder" if phase == "run" else "entered")
                   + ": S, S/S0 and the phase delay cover (the step in their budgets).")
    run.full_seeds = 400
    return run


_ENCODER_SCENARIOS = {f"response-encoder-{n}-lines": _encoder_lines_scenario(n, "entered") for n in (1024, 4096, 16384)}
_ENCODER_SCENARIOS["response-encoder-1024-lines+reference-run"] = _encoder_lines_scenario(1024, "run")


def _repeats(case: str, scatter: float, n_seeds: int, seed0: int) -> list[CoverageRow]:
    s, us, ts, r, ur, tr, d, ud, td, warned = ([] for _ in range(10))
    for seed in range(seed0, seed0 + n_seeds):
        recs, truth = simulate_centrifuge(frequencies=(5.0,) * 4, min_duration=_CF_DURATION,
                                          sensitivity_scatter=scatter, seed=seed)
        pts = [response_point(rec["output"], rec.time, input_amplitude=_A0, angle_deg=rec["angle"],
                              static_sensitivity=_S0, initial_phase=math.radians(truth["initial_phase_deg"]),
                              source=f"rec{i}") for i, rec in enumerate(recs)]
        (g,) = combine_repeats(pts)
        # truth of a mean over remountings: the sensor's mean sensitivity (the simulator's S0 |H|)
        t0 = truth["points"][0]
        s_true = _S0 * abs_h(truth, 5.0)
        kf = lambda b: b.coverage_factor / 2.0  # noqa: E731  (fold the stated k into u for the |e| <= 2u rows)
        s.append(g.sensitivity), us.append(kf(g.sensitivity_budget) * g.u_sensitivity), ts.append(s_true)
        r.append(g.normalized_sensitivity), ur.append(kf(g.normalized_budget) * g.u_normalized_sensitivity)
        tr.append(s_true / _S0)
        d.append(math.degrees(g.phase_delay)), ud.append(math.degrees(kf(g.phase_delay_budget) * g.u_phase_delay))
        td.append(t0["phase_delay_deg"])
        warned.append(has_warning(g.warnings, "excess-scatter"))
    note = "4 repeats, white noise" if not scatter else f"4 repeats, sensitivity varies {100 * scatter:g} % between them"
    w = warned if scatter else None
    return [coverage_row(JOB, case, "repeats mean S (k stated)", s, us, ts, warned=w, note=note),
            coverage_row(JOB, case, "repeats mean S/S0 (k stated)", r, ur, tr, warned=w, note=note),
            coverage_row(JOB, case, "repeats mean phase delay (k stated)", d, ud, td, note=note)]


def abs_h(truth: dict, f: float) -> float:
    """|H(f)| of the simulated second-order accelerometer."""
    from senscal.simulate.vibration import second_order_response

    return float(abs(second_order_response(f, truth["natural_frequency_hz"], truth["damping"])))


def run_repeats_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Four repeats at 5 Hz combined (combine_repeats), white noise (400 seeds)."""
    return _repeats("repeats-white", 0.0, n_seeds, seed0)


def run_repeats_remount(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Four repeats, sensitivity 0.1 % different each time: u from the spread, k = t(3), excess-scatter."""
    return _repeats("repeats-remount-0.1%", 1e-3, n_seeds, seed0)


run_repeats_white.full_seeds = 400
run_repeats_remount.full_seeds = 400


def _linearity(case: str, n_seeds: int, seed0: int, *, cubic: float = 0.0, scatter: float = 0.0,
               declared: bool = True) -> list[CoverageRow]:
    sl, usl, tsl, ic, uic, tic, li, uli, tli = ([] for _ in range(9))
    w_nr, w_xs = [], []
    x = np.asarray(_LEVELS)
    for seed in range(seed0, seed0 + n_seeds):
        recs, truth = simulate_centrifuge(frequencies=(1.0,), accelerations=_LEVELS, cubic=cubic,
                                          input_scatter=scatter, min_duration=_CF_DURATION, seed=seed)
        pts = [response_point(rec["output"], rec.time, input_amplitude=a, angle_deg=rec["angle"],
                              harmonics=3 if cubic else 1) for rec, a in zip(recs, _LEVELS)]
        lin = amplitude_linearity(x, [p.output_amplitude for p in pts], [p.u_output_amplitude for p in pts],
                                  u_input=scatter if declared else 0.0, seed=seed)
        # truth: the best straight line through the sensor's true outputs at the nominal levels
        h = abs_h(truth, 1.0)
        ax = x * h
        yt = _S0 * (ax + 0.75 * cubic * ax**3)
        b = np.polyfit(x, yt, 1)
        dev = yt - np.polyval(b, x)
        kf = lin.coverage_factor / 2.0
        sl.append(lin.slope), usl.append(kf * lin.u_slope), tsl.append(b[0])
        ic.append(lin.intercept), uic.append(kf * lin.u_intercept), tic.append(b[1])
        li.append(lin.linearity_percent), uli.append(lin.u_linearity_percent)
        tli.append(100 * np.max(np.abs(dev)) / np.max(yt))
        w_nr.append(has_warning(lin.warnings, "linearity-not-resolved"))
        w_xs.append(has_warning(lin.warnings, "linearity-excess-scatter"))
    note = ("linear sensor" if not cubic else f"cubic {cubic:g}") + (
        "" if not scatter else f", input levels scatter {100 * scatter:g} % ({'declared' if declared else 'not declared'})")
    line_w = w_xs if (scatter and not declared) else None
    line_e = "warn" if (scatter and not declared) else "cover"
    lin_w = w_xs if (scatter and not declared) else (w_nr if not cubic else None)
    lin_e = "warn" if (not cubic or (scatter and not declared)) else "cover"
    return [coverage_row(JOB, case, "linearity slope (k stated)", sl, usl, tsl, warned=line_w, expect=line_e, note=note),
            coverage_row(JOB, case, "linearity intercept (k stated)", ic, uic, tic, warned=line_w, expect=line_e,
                         note=note),
            coverage_row(JOB, case, "linearity %", li, uli, tli, warned=lin_w, expect=lin_e, note=note)]


def run_linearity_white(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Linear sensor, 5 levels: slope and intercept cover; the linearity says it is not resolved."""
    return _linearity("linearity-white", n_seeds, seed0)


def run_linearity_cubic(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """0.2 % cubic nonlinearity: slope, intercept and the (resolved) linearity cover."""
    return _linearity("linearity-cubic-2e-6", n_seeds, seed0, cubic=2e-6)


def run_linearity_scatter_declared(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Input levels 0.1 % off at random, declared as u_input: slope and intercept cover."""
    return _linearity("linearity-input-scatter-0.1%", n_seeds, seed0, scatter=1e-3)


def run_linearity_scatter_undeclared(n_seeds: int, seed0: int = 0) -> list[CoverageRow]:
    """Input levels 0.5 % off at random, not declared: linearity-excess-scatter fires."""
    return _linearity("linearity-input-scatter-0.5%-undeclared", n_seeds, seed0, scatter=5e-3, declared=False)


for _f in (run_linearity_white, run_linearity_cubic, run_linearity_scatter_declared, run_linearity_scatter_undeclared):
    _f.full_seeds = 400

SCENARIOS = {
    "velocity-white": run_velocity_white,
    "velocity-remount-0.1%": run_velocity_scatter,
    "velocity-swapped-channels": run_velocity_swapped,
    "velocity-position-mm-as-m": run_velocity_position_mm,
    "response-white": run_response_white,
    "response-encoder-zero-5deg": run_response_encoder_unknown,
    "response-encoder-zero-5deg+entered": run_response_encoder_entered,
    "response-encoder-zero-5deg+reference-run": run_response_encoder_run,
    **_ENCODER_SCENARIOS,
    "repeats-white": run_repeats_white,
    "repeats-remount-0.1%": run_repeats_remount,
    "linearity-white": run_linearity_white,
    "linearity-cubic-2e-6": run_linearity_cubic,
    "linearity-input-scatter-0.1%": run_linearity_scatter_declared,
    "linearity-input-scatter-0.5%-undeclared": run_linearity_scatter_undeclared,
}
