"""Streaming drift correction (issue 18 item 1): chunked == one pass, state across processes, honest u."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from senscal.drift import correct_drift, known_setup, redundant_setup
from senscal.drift.core import drift_prior
from senscal.drift.stream import DriftTracker, TrackerState
from senscal.errors import DataError, FileFormatError, InputError
from senscal.simulate.drift import simulate_drift_batch
from senscal.validation import CoverageRow, check_coverage, coverage_row, mc_seeds

REF = 20.0


@pytest.fixture(scope="module")
def record():
    """Two sensors (s1 trusted) with a random-walk bias and a temperature-linked one, 300 samples."""
    d = simulate_drift_batch(1, seed=11, n=300, covariate_coefficient=0.05)
    setup = redundant_setup(d["channels"], d["trusted"], covariate="c", covariate_reference=REF)
    return setup, d["y"][0], d["t"], d["covariate"][0]


@pytest.fixture(scope="module")
def one_pass(record):
    """correct_drift's filter and fixed-lag outputs, with its ML levels."""
    setup, y, t, c = record
    out = {}
    for lag in (0, 9):
        # The tracker keeps the levels it is given: compare with the one pass at those levels (no level u).
        out[lag] = correct_drift(setup, y, t, {"c": c}, window=lag or None, compare=False, level_u=False)
    return out


def _stream(setup, levels, y, t, c, cuts, lag, prior, *, restore_at=None, tmp=None):
    tr = DriftTracker(setup, levels, lag=lag, prior=prior)
    outs, i = [], 0
    for k, n in enumerate(cuts):
        outs.append(tr.update(y[:, i:i + n], t[i:i + n], {"c": c[i:i + n]}))
        i += n
        if restore_at == k:
            path = tr.state.save(tmp)
            tr = DriftTracker.from_state(TrackerState.load(path))
    assert i == t.size
    outs.append(tr.flush())
    cat = {k: np.concatenate([getattr(o, k) for o in outs], axis=-1)
           for k in ("t", "corrected", "bias", "u_bias", "state", "state_std")}
    return cat, tr


def _cuts(T, kind, lag):
    rng = np.random.default_rng(5)
    if kind == "one":
        return [T]
    if kind == "single":
        return [1] * T
    if kind == "split-window":  # chunks shorter than the lag window
        return [max(1, lag // 2)] * (T // max(1, lag // 2)) + [T % max(1, lag // 2)] * (T % max(1, lag // 2) > 0)
    cuts = []
    while sum(cuts) < T:
        cuts.append(int(min(rng.integers(1, 40), T - sum(cuts))))
    return cuts


@pytest.mark.parametrize("lag", [0, 9])
@pytest.mark.parametrize("kind", ["one", "single", "split-window", "random"])
def test_chunked_equals_one_pass(record, one_pass, lag, kind):
    setup, y, t, c = record
    res = one_pass[lag]
    levels = {p.name: p.value for p in res.noise}
    prior = drift_prior(setup, y, {"c": c - REF}, float(t[-1] - t[0]))
    got, tr = _stream(setup, levels, y, t, c, _cuts(t.size, kind, lag), lag, prior)
    np.testing.assert_array_equal(got["t"], t)
    scale = np.abs(res.bias).max()
    np.testing.assert_allclose(got["bias"], res.bias, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(got["u_bias"], res.bias_std, rtol=1e-9, atol=1e-12 * scale)
    np.testing.assert_allclose(got["corrected"], res.corrected, rtol=0, atol=1e-9 * np.abs(y).max())
    np.testing.assert_allclose(got["state"], res.state, rtol=0, atol=1e-9 * np.abs(res.state).max())
    assert tr.state.n_samples == tr.state.n_emitted == t.size
    assert tr.state.loglik == pytest.approx(res.loglik, rel=1e-9)


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_save_load_mid_window_continues_exactly(record, one_pass, tmp_path, suffix):
    setup, y, t, c = record
    levels = {p.name: p.value for p in one_pass[9].noise}
    prior = drift_prior(setup, y, {"c": c - REF}, float(t[-1] - t[0]))
    cuts = [100, 4, 196]
    ref, _ = _stream(setup, levels, y, t, c, cuts, 9, prior)
    got, _ = _stream(setup, levels, y, t, c, cuts, 9, prior, restore_at=1, tmp=tmp_path / f"s{suffix}")
    for k in ref:
        np.testing.assert_array_equal(got[k], ref[k])  # a restored state is exact, not merely close


def test_state_continues_across_processes(record, one_pass, tmp_path):
    """Yesterday's process saves, today's process loads: same numbers as one process."""
    setup, y, t, c = record
    levels = {p.name: p.value for p in one_pass[9].noise}
    prior = drift_prior(setup, y, {"c": c - REF}, float(t[-1] - t[0]))
    np.savez(tmp_path / "data.npz", y=y, t=t, c=c)
    tr = DriftTracker(setup, levels, lag=9, prior=prior)
    first = tr.update(y[:, :150], t[:150], {"c": c[:150]})
    tr.state.save(tmp_path / "state.json")
    script = (
        "import numpy as np, sys\n"
        "from senscal.drift.stream import DriftTracker, TrackerState\n"
        f"d = np.load({str(tmp_path / 'data.npz')!r})\n"
        f"tr = DriftTracker.from_state(TrackerState.load({str(tmp_path / 'state.json')!r}))\n"
        "a = tr.update(d['y'][:, 150:], d['t'][150:], {'c': d['c'][150:]})\n"
        "b = tr.flush()\n"
        f"np.savez({str(tmp_path / 'out.npz')!r}, bias=np.concatenate([a.bias, b.bias], 1),"
        " u=np.concatenate([a.u_bias, b.u_bias], 1))\n")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    other = np.load(tmp_path / "out.npz")
    rest = tr.update(y[:, 150:], t[150:], {"c": c[150:]})
    tail = tr.flush()
    np.testing.assert_array_equal(other["bias"], np.concatenate([rest.bias, tail.bias], 1))
    np.testing.assert_array_equal(other["u"], np.concatenate([rest.u_bias, tail.u_bias], 1))
    assert first.t.size == 150 - 9


def test_refuses_data_that_does_not_continue(record, one_pass, tmp_path):
    setup, y, t, c = record
    levels = {p.name: p.value for p in one_pass[0].noise}
    tr = DriftTracker(setup, levels)
    tr.update(y[:, :50], t[:50], {"c": c[:50]})
    with pytest.raises(DataError, match="does not continue"):
        tr.update(y[:, 40:60], t[40:60], {"c": c[40:60]})
    with pytest.raises(InputError, match="shape"):
        tr.update(y[:1, 50:60], t[50:60], {"c": c[50:60]})
    with pytest.raises(InputError, match="covariate c"):
        tr.update(y[:, 50:60], t[50:60])
    with pytest.raises(InputError, match="not given"):
        DriftTracker(setup, {"s1_noise_std": 0.1})
    bad = tmp_path / "bad.json"
    bad.write_text('{"format_version": 99}')
    with pytest.raises(FileFormatError, match="format_version"):
        TrackerState.load(bad)
    bad.write_text('{"format_version": 1, "setup": {}}')
    with pytest.raises(FileFormatError, match="not a valid drift tracker state"):
        TrackerState.load(bad)


def test_known_setup_with_missing_samples_matches_one_pass():
    """A known quantity (offset shifted) and NaN gaps: the shift and the gaps survive chunking."""
    d = simulate_drift_batch(1, seed=2, n=200, channels=("g",), trusted=(), signal="known", signal_mean=1.5)
    y = d["y"][0].copy()
    y[0, 50:53] = np.nan
    setup = known_setup(["g"], 1.5)
    res = correct_drift(setup, y, d["t"], window=5, compare=False)
    levels = {p.name: p.value for p in res.noise}
    prior = drift_prior(setup, y - 1.5, {}, float(d["t"][-1] - d["t"][0]))
    tr = DriftTracker(setup, levels, lag=5, prior=prior)
    parts = [tr.update(y[:, i:i + 7], d["t"][i:i + 7]) for i in range(0, 200, 7)] + [tr.flush()]
    bias = np.concatenate([p.bias for p in parts], 1)
    corr = np.concatenate([p.corrected for p in parts], 1)
    np.testing.assert_allclose(bias, res.bias, atol=1e-9)
    np.testing.assert_allclose(corr, res.corrected, atol=1e-9)
    assert np.isnan(corr[0, 50:53]).all()


def _band(case: str, z: np.ndarray, note: str) -> CoverageRow:
    """Pointwise band coverage pooled over time and seeds (n = seeds, conservative)."""
    ok = np.isfinite(z)
    return CoverageRow("drift", case, "bias band (streamed)", int(z.shape[0]),
                       float(np.mean(np.where(ok, np.abs(z) <= 2.0, False))), float(np.std(z[ok])), note=note)


def test_streamed_bias_band_covers():
    """Monte Carlo: levels by ML on day 1, day 2 streamed in chunks with the saved state.

    The model of validation.drift's ``white`` scenario (random-walk quantity
    and bias, white noise).  The band of the streamed bias (filter and a
    20-sample window) must cover the true bias 95 % of the time, pointwise and
    at the end of the second day.
    """
    n_seeds = mc_seeds(200, 40)
    # Day 1 long enough for the bias rate to show (its random walk wanders
    # 3x the noise): on a day of 300 samples the ML rate collapses to zero in
    # about one seed in ten, and the stream then holds the bias constant
    # (the job names that with ``drift-levels-uncertain``).
    half, day2 = 900, 300
    d = simulate_drift_batch(n_seeds, seed=700, n=half + day2, noise=0.1, signal_level=0.1, bias_rate=0.01)
    setup = redundant_setup(["s1", "s2"], trusted=["s1"])
    rows = []
    for lag in (0, 20):
        z, fin, fin_u, truth = [], [], [], []
        for s in range(n_seeds):
            y, t = d["y"][s], d["t"]
            day1 = correct_drift(setup, y[:, :half], t[:half], compare=False)
            levels = {p.name: p.value for p in day1.noise}
            tr = DriftTracker(setup, levels, lag=lag,
                              prior=drift_prior(setup, y[:, :half], {}, float(t[half - 1] - t[0])))
            tr.update(y[:, :half], t[:half])
            parts = [tr.update(y[:, i:i + 37], t[i:i + 37]) for i in range(half, half + day2, 37)] + [tr.flush()]
            tt = np.concatenate([p.t for p in parts])
            b = np.concatenate([p.bias[0] for p in parts])
            u = np.concatenate([p.u_bias[0] for p in parts])
            keep = tt >= t[half]
            tb = d["bias"][s, 1][np.searchsorted(t, tt[keep])]
            z.append((b[keep] - tb) / u[keep])
            fin.append(b[-1])
            fin_u.append(u[-1])
            truth.append(d["bias"][s, 1, -1])
        note = f"day 2 streamed in 37-sample chunks, lag {lag}"
        rows.append(_band(f"streamed lag {lag}", np.array(z), note))
        rows.append(coverage_row("drift", f"streamed lag {lag}", "final bias of s2", fin, fin_u, truth, note=note))
    check_coverage(rows)
