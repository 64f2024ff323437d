"""Fleet drift correction: kernels against DriftTracker, Dask against one process, state across runs."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from senscal.drift import covariate_setup, known_setup
from senscal.drift.fleet import (FleetGroup, FleetOptions, ROLE, _Client, filter_block, fleet, load_fleet_config,
                                 read_store, run_fleet)
from senscal.drift.stream import DriftTracker
from senscal.errors import DataError, FileFormatError, InputError
from senscal.simulate.fleet import simulate_fleet
from senscal.validation import check_coverage, coverage_row, mc_seeds

KNOWN = {"y_noise_std": 0.05, "y_bias_rate_std": 1e-3}
COV = {"y_noise_std": 0.05, "signal_rate_std": 1e-3, "y_temperature_coefficient_rate_std": 1e-4}
CUTS = [0, 1, 300, 301, 700, 1000]   # chunks of one sample, and ones that do not divide the record


def _known_data(rng, C, T, missing=0.0):
    y = np.cumsum(rng.normal(0, 1e-3, (C, T)), axis=1) + rng.normal(0, 0.05, (C, T))
    y[rng.random(y.shape) < missing] = np.nan
    return y


def _cov_data(rng, C, T):
    t = np.arange(T, dtype=float)
    temp = 20 + 5 * np.sin(2 * np.pi * t / 300 + rng.uniform(0, 6, (C, 1)))
    y = np.cumsum(rng.normal(0, 1e-3, (C, T)), axis=1) + 0.01 * (temp - 20) + rng.normal(0, 0.05, (C, T))
    return y, temp[:, None, :]


def _chunked(group, y, t, cov=None, cuts=CUTS, **kw):
    states = [None] * y.shape[0]
    bias, std = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        bb, ss, states = filter_block(group, y[:, a:b], t[a:b], states, None if cov is None else cov[:, :, a:b], **kw)
        bias.append(bb)
        std.append(np.broadcast_to(ss, bb.shape))
    return np.hstack(bias), np.hstack(std), states


def _tracker(setup, levels, y, t, cov=None, prior=None, cuts=CUTS):
    tr = DriftTracker(setup, levels, prior=prior)
    outs = [tr.update(y[None, a:b], t[a:b], None if cov is None else {"temperature": cov[0, a:b]})
            for a, b in zip(cuts[:-1], cuts[1:])]
    return np.hstack([o.bias[0] for o in outs]), np.hstack([o.u_bias[0] for o in outs]), tr


@pytest.mark.parametrize("case", ["shared", "missing", "per-channel-levels", "covariate"])
def test_block_kernels_match_drift_tracker_per_channel(case):
    rng = np.random.default_rng(11)
    C, T = 5, CUTS[-1]
    t = np.arange(T) * 2.0
    cov = None
    if case == "covariate":
        setup, levels = covariate_setup(ROLE, "temperature", covariate_reference=20.0), COV
        y, cov = _cov_data(rng, C, T)
        group = FleetGroup("g", setup, levels)
    else:
        setup, levels = known_setup([ROLE]), KNOWN
        y = _known_data(rng, C, T, missing=0.1 if case == "missing" else 0.0)
        per = {"1": {"y_bias_rate_std": 3e-3}, "3": {"y_noise_std": 0.1}} if case == "per-channel-levels" else {}
        group = FleetGroup("g", setup, levels, prior_scale=0.05, channel_levels=per)
    # A covariate prior needs the covariate's spread over the first chunk: no one-sample first chunk there.
    cuts = [0] + CUTS[3:] if case == "covariate" else CUTS
    bias, std, states = _chunked(group, y, t, cov, cuts=cuts, channels=[str(c) for c in range(C)])
    for c in range(C):
        lv = group.all_levels(str(c))
        bt, ut, tr = _tracker(setup, lv, y[c], t, None if cov is None else cov[c], prior=(states[c].x0, states[c].P0),
                              cuts=cuts)
        np.testing.assert_allclose(bias[c], bt, rtol=1e-9, atol=1e-12 * np.abs(bt).max())
        np.testing.assert_allclose(std[c], ut, rtol=1e-9)
        np.testing.assert_allclose(states[c].x, tr.state.x, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(states[c].P, tr.state.P, rtol=1e-9, atol=1e-20)


def test_default_prior_is_the_trackers_first_chunk_rule():
    rng = np.random.default_rng(2)
    y = _known_data(rng, 3, 1000)
    t = np.arange(1000.0)
    group = FleetGroup("g", known_setup([ROLE]), KNOWN)   # no prior_scale: each channel's own spread
    bias, std, _ = _chunked(group, y, t)
    for c in range(3):
        bt, ut, _ = _tracker(group.setup, KNOWN, y[c], t)   # the tracker's default prior
        np.testing.assert_allclose(bias[c], bt, rtol=1e-9, atol=1e-12)


def test_shared_kernel_equals_per_channel_kernel():
    rng = np.random.default_rng(5)
    y = _known_data(rng, 40, 1000)
    t = np.arange(1000.0)
    group = FleetGroup("g", known_setup([ROLE]), KNOWN, prior_scale=0.05)
    b1, s1, st1 = _chunked(group, y, t, shared=True)
    b2, s2, st2 = _chunked(group, y, t, shared=False)
    np.testing.assert_allclose(b1, b2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(s1, s2, rtol=1e-12)
    with pytest.raises(InputError, match="do not share"):
        filter_block(FleetGroup("g", known_setup([ROLE]), KNOWN), y, t, [None] * 40, shared=True)


def test_bias_uncertainty_covers_the_truth():
    """Coverage of the final bias over many independent channels (each one seed)."""
    n = mc_seeds(2000, 400)
    rng = np.random.default_rng(7)
    T = 1500
    b = np.cumsum(rng.normal(0, KNOWN["y_bias_rate_std"], (n, T)), axis=1)
    y = b + rng.normal(0, KNOWN["y_noise_std"], (n, T))
    group = FleetGroup("g", known_setup([ROLE]), KNOWN, prior_scale=0.05)
    bias, std, _ = filter_block(group, y, np.arange(T, dtype=float), [None] * n)
    rows = [coverage_row("drift-fleet", "random-walk bias", f"bias@{i}", bias[:, i], std[i], b[:, i])
            for i in (T // 2, T - 1)]
    check_coverage(rows)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    truth = simulate_fleet(d / "data", n_channels=20, n_samples=2000, channels_per_file=5, rows_per_group=400,
                           kind="known", segments=2, missing=0.01, seed=4)
    return d, truth


def _full_tracker_bias(truth, channel, prior):
    """One DriftTracker over both days of one channel (files read whole)."""
    ys, ts = [], []
    for seg in truth["segments"]:
        for f in sorted(__import__("pathlib").Path(seg).glob("*.parquet")):
            tb = pq.read_table(f)
            if channel in tb.column_names:
                ys.append(tb.column(channel).to_numpy())
                ts.append(tb.column("t").to_numpy())
    tr = DriftTracker(known_setup([ROLE]), truth["config"]["groups"][0]["levels"], prior=prior)
    out = tr.update(np.concatenate(ys)[None], np.concatenate(ts))
    return tr, out


def test_two_days_on_local_cluster_match_one_process_and_tracker(dataset, tmp_path):
    d, truth = dataset
    groups = load_fleet_config(d / "data" / "fleet.json")
    seg0, seg1 = truth["segments"]
    local = [run_fleet(seg, groups, state=tmp_path / "s1") for seg in (seg0, seg1)]
    # One cluster for both days (starting one costs seconds), as a monitoring service would keep it.
    with _Client(2, None) as client:
        dist = [run_fleet(seg, groups, state=tmp_path / "s2", out=tmp_path / "out", client=client)
                for seg in (seg0, seg1)]
    assert dist[1].workers == 2 and local[1].workers == 0
    assert local[1].channels == dist[1].channels and len(local[1].channels) == 20
    np.testing.assert_array_equal(local[1].bias, dist[1].bias)
    np.testing.assert_array_equal(local[1].u_bias, dist[1].u_bias)
    assert local[1].n_samples == 20 * 1000 and local[1].t_last.max() == 1999.0
    store = read_store(tmp_path / "s1")
    for c in ("s00000", "s00013"):
        _, st, b, u = store[c]
        tr, out = _full_tracker_bias(truth, c, (st.x0, st.P0))
        np.testing.assert_allclose(st.x, tr.state.x, rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(st.P, tr.state.P, rtol=1e-9)
        i = local[1].channels.index(c)
        assert local[1].bias[i] == pytest.approx(out.bias[0, -1], rel=1e-9)
        assert local[1].u_bias[i] == pytest.approx(out.u_bias[0, -1], rel=1e-9)
        # A channel continues alone with the stream API from the fleet's state.
        assert st.tracker_state(groups[0]).n_samples == 2000
    # The corrected data: every sample of both days once.
    files = sorted((tmp_path / "out").rglob("*.parquet"))
    assert sum(pq.read_metadata(f).num_rows for f in files) == 4 * 2000   # 4 blocks, both days
    # The truth lies within the stated uncertainty for most channels.
    z = (local[1].bias - np.array([truth["final_bias"][c] for c in local[1].channels])) / local[1].u_bias
    assert np.mean(np.abs(z) <= 2) >= 0.75


def test_crash_loses_only_the_chunk_in_flight(dataset, tmp_path, monkeypatch):
    d, truth = dataset
    groups = load_fleet_config(d / "data" / "fleet.json")
    seg0 = truth["segments"][0]
    ref = run_fleet(seg0, groups, state=tmp_path / "ref")
    import senscal.drift.fleet as fl

    real = fl.filter_block
    calls = {"n": 0}

    def dying(*a, **k):
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt  # killed in the middle of a block
        return real(*a, **k)

    monkeypatch.setattr(fl, "filter_block", dying)
    with pytest.raises(KeyboardInterrupt):
        run_fleet(seg0, groups, state=tmp_path / "s")
    monkeypatch.setattr(fl, "filter_block", real)
    saved = read_store(tmp_path / "s")
    # Block 0 finished (3 row groups), block 1 saved its first row group and died in its second.
    assert sorted({st.t_last for _, st, _, _ in saved.values()}) == [399.0, 999.0] and len(saved) == 10
    again = run_fleet(seg0, groups, state=tmp_path / "s")
    np.testing.assert_allclose(again.bias, ref.bias, rtol=1e-12)
    assert any(w.startswith("fleet-rows-skipped") for w in again.warnings)
    # A state file is always whole: nothing half-written is left beside it.
    assert not [p for p in (tmp_path / "s").iterdir() if p.name.startswith(".")]


def test_store_refuses_other_levels_and_bad_configs(dataset, tmp_path):
    d, truth = dataset
    groups = load_fleet_config(d / "data" / "fleet.json")
    run_fleet(truth["segments"][0], groups, state=tmp_path / "s")
    other = (FleetGroup(groups[0].name, groups[0].setup, {**groups[0].levels, "y_noise_std": 0.1},
                        prior_scale=groups[0].prior_scale),)
    with pytest.raises(InputError, match="another set-up, levels"):
        run_fleet(truth["segments"][1], other, state=tmp_path / "s")
    with pytest.raises(InputError, match="needs the noise levels"):
        FleetGroup("g", known_setup([ROLE]), {"y_noise_std": 0.05})
    with pytest.raises(InputError, match="needs a reference"):
        FleetGroup("g", covariate_setup(ROLE, "temperature"), COV)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"groups": [{"name": "g", "setup": {"preset": "nope"}}]}))
    with pytest.raises(FileFormatError, match="preset"):
        load_fleet_config(bad)
    with pytest.raises(InputError, match="does not exist"):
        run_fleet(tmp_path / "nothing", groups)


def test_covariate_fleet_and_time_going_backwards(tmp_path):
    truth = simulate_fleet(tmp_path / "cov", n_channels=4, n_samples=600, channels_per_file=2, rows_per_group=200,
                           kind="covariate", seed=1)
    groups = load_fleet_config(tmp_path / "cov" / "fleet.json")
    res = run_fleet(tmp_path / "cov", groups)
    assert res.shared_chunks == 0 and res.chunks == 2 * 3 and np.all(res.u_bias > 0)
    # Per-channel covariances: each channel as its own tracker.
    f = sorted((tmp_path / "cov").glob("*.parquet"))[0]
    tb = pq.read_table(f)
    y, t, c = tb.column("s00000").to_numpy(), tb.column("t").to_numpy(), tb.column("s00000.temperature").to_numpy()
    _, _, states = _chunked_file(groups[0], y, t, c)
    bt, ut, _ = _tracker(groups[0].setup, groups[0].levels, y, t, c[None], prior=(states.x0, states.P0),
                         cuts=[0, 200, 400, 600])
    assert res.bias[0] == pytest.approx(bt[-1], rel=1e-9) and res.u_bias[0] == pytest.approx(ut[-1], rel=1e-9)
    with pytest.raises(DataError, match="not after the stored state"):
        filter_block(groups[0], y[None, :10], t[:10], [states], c[None, None, :10])


def _chunked_file(group, y, t, c):
    st = [None]
    for a in (0, 200, 400):
        _, _, st = filter_block(group, y[None, a:a + 200], t[a:a + 200], st, c[None, None, a:a + 200])
    return None, None, st[0]


def test_a_channel_that_missed_a_sample_rejoins_the_shared_covariance():
    rng = np.random.default_rng(9)
    group = FleetGroup("g", known_setup([ROLE]), KNOWN, prior_scale=0.05)
    C, T = 30, 600
    states = [None] * C
    kinds = []
    for k in range(5):
        y = _known_data(rng, C, T)
        if k == 1:
            y[4, 50] = np.nan
        bias, std, states = filter_block(group, y, np.arange(k * T, (k + 1) * T, dtype=float), states)
        kinds.append(std.ndim)
        assert np.all(np.isfinite(bias))
    assert kinds[0] == 1 and kinds[1] == 2 and kinds[-1] == 1


def test_a_channel_new_on_day_two_starts_beside_the_others(tmp_path):
    import pyarrow as pa

    rng = np.random.default_rng(3)
    y = _known_data(rng, 3, 800)
    t = np.arange(800.0)
    (tmp_path / "d1").mkdir()
    (tmp_path / "d2").mkdir()
    pq.write_table(pa.table({"t": t[:400], "a": y[0, :400], "b": y[1, :400]}), tmp_path / "d1" / "p.parquet",
                   row_group_size=150)
    pq.write_table(pa.table({"t": t[400:], "a": y[0, 400:], "b": y[1, 400:], "c": y[2, 400:]}),
                   tmp_path / "d2" / "p.parquet", row_group_size=150)
    groups = (FleetGroup("g", known_setup([ROLE]), KNOWN, prior_scale=0.05),)
    run_fleet(tmp_path / "d1", groups, state=tmp_path / "s")
    res = run_fleet(tmp_path / "d2", groups, state=tmp_path / "s")
    assert res.channels == ("a", "b", "c") and res.n_samples == 3 * 400
    store = read_store(tmp_path / "s")
    cuts1, cuts2 = [0, 150, 300, 400], [400, 550, 700, 800]
    for i, c in enumerate("abc"):
        _, st, _, _ = store[c]
        cuts = cuts1 + cuts2[1:] if c != "c" else cuts2
        bt, ut, tr = _tracker(groups[0].setup, KNOWN, y[i], t, prior=(st.x0, st.P0), cuts=cuts)
        assert res.bias[i] == pytest.approx(bt[-1], rel=1e-9) and res.u_bias[i] == pytest.approx(ut[-1], rel=1e-9)
        assert st.n_samples == (800 if c != "c" else 400)


def test_job_function_result_document_quantities_table(dataset, tmp_path):
    d, truth = dataset
    seg0 = truth["segments"][0]
    res = fleet(seg0, FleetOptions(config=str(d / "data" / "fleet.json"), workers=0))
    ref = run_fleet(seg0, load_fleet_config(d / "data" / "fleet.json"))
    np.testing.assert_array_equal(res.bias, ref.bias)
    doc = res.to_dict()
    assert doc["n_channels"] == 20 and doc["n_samples"] == 20 * 1000 and doc["n_missing"] == res.n_missing > 0
    assert set(doc["channels"]["s00007"]) == {"group", "bias", "u_bias", "t_last"}
    q = {x.name: x for x in res.quantities()}
    assert q["s00007.bias"].value == doc["channels"]["s00007"]["bias"] and q["s00007.bias"].uncertainty > 0
    df = res.to_dataframe()
    assert list(df.columns) == ["channel", "group", "bias", "u_bias", "t_last"] and len(df) == 20
    with pytest.raises(InputError, match="--config"):
        fleet(seg0, FleetOptions())
