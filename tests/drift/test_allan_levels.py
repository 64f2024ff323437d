"""``--levels-from-allan``: drift noise levels read off Allan deviations (issue 18 item 3)."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.drift import known_setup, redundant_setup
from senscal.drift.allan import drift_levels_from_allan
from senscal.errors import InputError
from senscal.simulate.drift import simulate_drift_batch

SEEDS = 8


def _unbiased(est: np.ndarray, truth: float, name: str) -> None:
    """The seeds' mean relative error is within 3 standard errors of zero (an estimator bias fails)."""
    rel = np.asarray(est) / truth - 1.0
    se = rel.std(ddof=1) / np.sqrt(rel.size)
    assert abs(rel.mean()) <= 3 * se + 1e-12, f"{name}: mean relative error {rel.mean():+.3f} (se {se:.3f})"


@pytest.mark.parametrize("noise, rate, dt", [(0.1, 0.01, 1.0), (0.02, 0.003, 2.0)])
def test_known_quantity_levels(noise, rate, dt):
    """A sensor at rest: per-sample white std and random-walk bias rate, whatever the sample interval."""
    d = simulate_drift_batch(SEEDS, seed=40, n=20000, dt=dt, channels=("g",), trusted=(), signal="known",
                             noise=noise, bias_rate=rate)
    setup = known_setup(["g"])
    got = [drift_levels_from_allan(setup, d["y"][s], d["t"]) for s in range(SEEDS)]
    assert set(got[0]) == {"g_noise_std", "g_bias_rate_std"}
    _unbiased([g["g_noise_std"] for g in got], noise, "noise std")
    _unbiased([g["g_bias_rate_std"] for g in got], rate, "bias rate")


@pytest.mark.parametrize("channels", [("s1", "s2"), ("s1", "s2", "s3")])
def test_redundant_levels_cancel_the_quantity(channels):
    """The quantity (a random walk 10x the bias rate) cancels in the differences; its rate comes from the trusted sensor."""
    d = simulate_drift_batch(SEEDS, seed=90, n=20000, channels=channels, trusted=("s1",), noise=0.05,
                             signal_level=0.1, bias_rate=0.01)
    setup = redundant_setup(list(channels), ["s1"])
    got = [drift_levels_from_allan(setup, d["y"][s], d["t"]) for s in range(SEEDS)]
    assert set(got[0]) == set(setup.level_names())
    for c in channels:
        _unbiased([g[f"{c}_noise_std"] for g in got], 0.05, f"{c} noise")
    for c in channels[1:]:
        _unbiased([g[f"{c}_bias_rate_std"] for g in got], 0.01, f"{c} bias rate")
    _unbiased([g["signal_rate_std"] for g in got], 0.1, "signal rate")


def test_no_wander_gives_a_small_rate_and_gaps_are_refused():
    d = simulate_drift_batch(1, seed=3, n=4000, channels=("g",), trusted=(), signal="known", noise=0.1, bias="none")
    lv = drift_levels_from_allan(known_setup(["g"]), d["y"][0], d["t"], with_u=True)
    value, u = lv["g_bias_rate_std"]
    assert value < 0.01 * 0.1 and u > 0
    y = d["y"][0].copy()
    y[0, 5] = np.nan
    with pytest.raises(InputError, match="gap-free"):
        drift_levels_from_allan(known_setup(["g"]), y, d["t"])


def test_cli_levels_from_allan_reaches_the_same_maximum(cli, tmp_path):
    """--levels-from-allan only moves the search's start: the maximum-likelihood levels are the same."""
    import json

    r = cli("simulate", "drift", "--layout", "known", "--samples", "3000", "--out", tmp_path, "--seed", "2")
    assert r.code == 0, r.err
    docs = []
    for extra in ([], ["--levels-from-allan"]):
        r = cli("drift", tmp_path / "drift.csv", "--preset", "known", "--no-compare", "--json", *extra)
        assert r.code == 0, r.err
        docs.append(json.loads(r.out))
    a, b = docs
    # The search (L-BFGS-B, ftol 1e-5 / T) stops where the likelihood no longer moves: two starts of one
    # smooth maximum agree to a small fraction of a nat, and the levels to well under their uncertainty.
    assert abs(a["loglik"] - b["loglik"]) < 1e-3
    for k, v in a["noise"].items():
        assert b["noise"][k]["value"] == pytest.approx(v["value"], rel=1e-3)
