"""``frequency-mismatch`` (issue 31 item 5): a --freq the data do not have is named; a right one almost never.

The check rejects ``f0`` when the free-frequency fit's ``z = (f - f0) / u(f)`` exceeds 3.29 (two-sided
0.1 %), so under a right ``--freq`` it fires in 0.1 % of records if ``u(f)`` is honest.  With ``n`` records
the number of false alarms is binomial(n, 0.001); the test allows up to the count whose upper tail is below
1e-4, so it fails only for a false-alarm rate several times the nominal one (white and AR(1) noise).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from senscal.sinefit.freqcheck import Z_REJECT, frequency_mismatch
from senscal.simulate.sine import simulate_sine
from senscal.validation import mc_seeds


def _allowed(n: int, p: float = 2 * stats.norm.sf(Z_REJECT), tail: float = 1e-4) -> int:
    """Largest false-alarm count whose binomial(n, p) upper tail is still above ``tail``."""
    return int(stats.binom.isf(tail, n, p))


def test_cli_names_a_wrong_frequency(cli, tmp_path):
    rec, _ = simulate_sine(n_channels=1, duration=1.0, frequency=12.5, noise=0.05, seed=4)
    from senscal.io import write_recording

    f = write_recording(rec, tmp_path / "sine.csv")
    r = cli("fit", f, "--freq", "10", "--json", "--strict")
    assert r.code == 3
    warns = json.loads(r.out)["warnings"]
    hit = [w for w in warns if w.startswith("frequency-mismatch:")]
    assert hit and "12.5" in hit[0] and "--freq 10" in hit[0]
    ok = cli("fit", f, "--freq", "12.5", "--json")
    assert ok.code == 0 and not [w for w in json.loads(ok.out)["warnings"] if w.startswith("frequency-mismatch")]


@pytest.mark.parametrize("given", [12.0, 12.4, 13.0, 25.0, 6.25])
def test_wrong_frequencies_are_named(given):
    rec, _ = simulate_sine(n_channels=1, duration=2.0, frequency=12.5, noise=0.05, seed=2)
    w = frequency_mismatch(rec["ch1"], rec.time, given, name="ch1")
    assert w is not None and w.startswith("frequency-mismatch: channel 'ch1'")


@pytest.mark.parametrize("rho", [0.0, 0.6])
def test_right_frequency_false_alarms_are_rare(rho):
    n = mc_seeds(400, 150)
    alarms = 0
    for seed in range(n):
        rec, truth = simulate_sine(n_channels=1, duration=0.5, frequency=12.5, noise=0.2, noise_rho=rho, seed=seed)
        alarms += frequency_mismatch(rec["ch1"], rec.time, 12.5) is not None
    assert alarms <= _allowed(n), (alarms, n)


def test_periodogram_fallback_when_the_free_fit_fails(monkeypatch):
    """Without a free-frequency fit (it raised), the periodogram peak is compared, one bin 1/T as tolerance."""
    import senscal.sinefit
    from senscal.errors import DataError

    def broken(*a, **k):
        raise DataError("no fit")

    monkeypatch.setattr(senscal.sinefit, "fit_sine", broken)
    t = np.arange(1000) / 1000.0
    y = np.sin(2 * np.pi * 25.0 * t)
    w = frequency_mismatch(y, t, 8.0)
    assert w is not None and "spectral peak is at 25 Hz" in w
    assert frequency_mismatch(y, t, 25.6) is None  # within one bin (1 Hz)
