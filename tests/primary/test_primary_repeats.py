"""Repeated mountings at one frequency: the data-based check of transverse motion (issue 28).

Transverse motion is a constant complex factor of one record's fundamental, invisible to it; remounted, the
factor changes, and the repeats' scatter beyond the u that varies between mountings is named
``mounting-repeats-disagree``. The rates over 200 seeds are the ``remounted`` and ``remounted-transverse``
scenarios (test_coverage_primary.py).
"""

from __future__ import annotations

import functools
import math

import pytest

from senscal.jobs.primary import PrimaryOptions, primary
from senscal.primary import calibrate_point
from senscal.primary.repeats import repeat_warnings
from senscal.simulate.interferometer import simulate_interferometer

F, FS, DUR = 160.0, 100_000.0, 0.5


@functools.lru_cache(maxsize=None)
def _records(transverse: float, seed0: int, n: int = 4, freq: float = F):
    return tuple(simulate_interferometer(freq=freq, fs=FS, duration=DUR, seed=seed0 + i, transverse_rel=transverse)
                 for i in range(n))


def _points(transverse, seed0, **kw):
    return [calibrate_point(r.channels["I"], r.channels["Q"], r.channels["out"], r.fs, freq=F, **kw)
            for r, _ in _records(transverse, seed0)]


def test_repeats_without_transverse_motion_agree():
    assert repeat_warnings(_points(0.0, 100)) == ()


def test_unstated_transverse_motion_is_named_across_mountings():
    w = repeat_warnings(_points(0.002, 200))
    assert len(w) == 1 and w[0].startswith("mounting-repeats-disagree: the 4 points at 160 Hz")


def test_stated_transverse_motion_is_not_named():
    """Stated as the 'other' type B (per mounting), the scatter is within the u that varies between mountings."""
    pts = _points(0.002, 200, u_other_rel=0.002, u_other_phase_deg=math.degrees(0.002))
    assert repeat_warnings(pts) == ()


def test_single_points_and_other_frequencies_are_not_compared():
    pts = _points(0.002, 200)
    assert repeat_warnings(pts[:1]) == ()
    (r, _), = _records(0.002, 300, n=1, freq=1000.0)
    other = calibrate_point(r.channels["I"], r.channels["Q"], r.channels["out"], r.fs, freq=1000.0)
    assert repeat_warnings([pts[0], other]) == ()


@pytest.mark.parametrize("transverse, named", [(0.0, False), (0.002, True)])
def test_the_job_names_disagreeing_mountings(transverse, named):
    recs = [r for r, _ in _records(transverse, 100 if not transverse else 200)]
    res = primary(recs, PrimaryOptions(freq=F))
    assert any(w.startswith("mounting-repeats-disagree") for w in res.warnings) is named
