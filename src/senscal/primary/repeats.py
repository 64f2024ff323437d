"""Repeated points at one frequency: the data-based check of transverse and rocking motion (issue 28).

Transverse (parasitic) motion reaches the output through the accelerometer's transverse sensitivity as a
constant complex factor of the fundamental: in one record it is indistinguishable from the sensitivity
itself (no per-period fit and no residual test can see it; the beam watches the axial motion). It changes
with the mounting: turned about its axis, the sensor's transverse axis meets the table's transverse motion at
another angle (ISO 16063-11 asks for repeated mountings and, for rocking, several beam positions). Points
repeated at one frequency after remounting then scatter by it, and their scatter against the u that varies
between them is the check.
"""

from __future__ import annotations

import math

import numpy as np

from senscal.diagnostics import named

__all__ = ["REPEAT_ALPHA", "repeat_warnings"]

# family false-alarm rate of the check at one frequency (magnitude and phase, Bonferroni)
REPEAT_ALPHA = 0.01
# the components that differ between mountings: the fits' noise, the unmodelled residual, the ellipse, the
# frequency, and the stated 'other' type B (transverse, rocking, mounting), which a lab states per mounting. The
# wavelength, the output gain's calibration and a heterodyne demodulation filter are common to every repeat
# and cancel in their differences.
_VARYING = ("displacement_fit", "output_fit", "unmodelled_slices", "heydemann", "frequency", "other")


def repeat_warnings(points, rel_tol: float = 1e-6) -> tuple[str, ...]:
    """Named warnings for points repeated at one frequency that disagree beyond their varying u.

    Parameters
    ----------
    points : iterable of PrimaryPoint
        The calibration's points (any order).
    rel_tol : float
        Frequencies within this relative difference are one frequency.

    Returns
    -------
    tuple of str
        ``mounting-repeats-disagree`` per frequency whose repeats fail the chi-square test of consistency
        (magnitude relative to their weighted mean, phase in deg; each at ``REPEAT_ALPHA / 2``, ``k - 1``
        degrees of freedom) with the u of the components that vary between mountings (:data:`_VARYING`).
    """
    from senscal.consistency import block_consistency

    pts = sorted(points, key=lambda p: p.frequency_hz)
    groups: list[list] = []
    for p in pts:
        if groups and abs(p.frequency_hz - groups[-1][0].frequency_hz) <= rel_tol * abs(p.frequency_hz):
            groups[-1].append(p)
        else:
            groups.append([p])
    out = []
    for g in groups:
        k = len(g)
        if k < 2:
            continue
        s = np.array([p.sensitivity for p in g], float)
        ph = np.array([p.phase_deg for p in g], float)
        u_rel = np.array([math.sqrt(sum(p.budget[c]["u_rel"] ** 2 for c in _VARYING if c in p.budget)) for p in g])
        u_ph = np.array([math.sqrt(sum(p.budget[c]["u_phase_deg"] ** 2 for c in _VARYING if c in p.budget))
                         for p in g])
        if not (np.all(u_rel > 0) and np.all(u_ph > 0) and np.all(np.isfinite(s)) and np.all(s != 0)):
            continue
        ref = float(np.mean(s))
        # The weighted-mean chi-square test of the block refits, each repeat a block (magnitude relative to
        # the mean; phase in rad, unwrapped about the first), at REPEAT_ALPHA over the two quantities.
        rad = np.radians(ph)
        test = block_consistency(lambda i: {"magnitude": (s[i[0]] / ref, u_rel[i[0]]),
                                            "phase": (rad[i[0]], math.radians(u_ph[i[0]]))},
                                 [np.array([i]) for i in range(k)], alpha=REPEAT_ALPHA, circular=("phase",))
        chi = {q.name: q.chi2 for q in test.quantities}
        c_s, c_p = chi.get("magnitude", math.nan), chi.get("phase", math.nan)
        if not test.consistent:
            spread_rel = float(np.std(s, ddof=1) / abs(ref))
            spread_ph = float(np.std(ph, ddof=1))
            out.append(named("mounting-repeats-disagree", (
                f"the {k} points at {g[0].frequency_hz:g} Hz scatter {spread_rel:.2g} (magnitude, sd) and "
                f"{spread_ph:.2g} deg (phase), {math.sqrt(c_s / (k - 1)):.1f}x and {math.sqrt(c_p / (k - 1)):.1f}x "
                "their u that varies between mountings: the mounting changes the result (transverse or rocking "
                "motion through the transverse sensitivity, mounting torque, cable); state it as --u-other-rel "
                "and --u-other-phase-deg (at least the scatter) or average the mountings")))
    return tuple(out)
