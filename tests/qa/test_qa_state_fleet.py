"""QA: ``senscal drift --state`` and ``senscal drift-fleet`` on broken states, datasets and configurations.

Each case below was an internal error (exit 1), a silent skip or a modified
input before; now one line on stderr (exit 2), the inputs and the previous
state untouched.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest

OPTS = ["--preset", "redundant", "--trusted", "s1", "--channels", "s1,s2", "--no-compare"]


def _main(*args) -> int:
    from senscal.cli import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
        except SystemExit as exc:
            assert exc.code in (0, None), err.getvalue()
    return 0


def _one_line(r, match=""):
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err
    lines = [ln for ln in r.err.splitlines() if ln.strip() and not ln.startswith("warning:")]
    assert len(lines) == 1 and lines[0].startswith("senscal: "), r.err
    assert match in r.err, r.err


def _digest(*paths: Path) -> dict:
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for p in paths
            for f in ([p] if p.is_file() else sorted(p.rglob("*"))) if f.is_file()}


@pytest.fixture(scope="module")
def days(tmp_path_factory):
    """Two days of a pair of sensors, and the state after day 1 (JSON and NPZ)."""
    from senscal.io import Recording, read_recording, write_recording

    d = tmp_path_factory.mktemp("state")
    _main("simulate", "drift", "--out", d / "sim", "--seed", "2", "--layout", "pair", "--samples", "400")
    rec = read_recording(d / "sim" / "drift.csv")
    half = rec.n_samples // 2
    paths = [write_recording(Recording({c: rec[c][sl] for c in rec.names}, t=rec.time[sl]), d / f"day{i}.csv")
             for i, sl in enumerate((slice(0, half), slice(half, None)), start=1)]
    from senscal.drift.stream import DriftTracker
    from senscal.jobs.drift import DriftOptions, drift_setup_for

    # The state day 1 leaves, built with the simulator's levels (the likelihood search is not under test here).
    setup = drift_setup_for(rec, DriftOptions(preset="redundant", trusted=("s1",), channels=("s1", "s2")))
    levels = {k: 0.05 if k.endswith("noise_std") else 0.01 for k in setup.level_names()}
    tracker = DriftTracker(setup, levels)
    tracker.update(rec.data(["s1", "s2"])[:, :half], rec.time[:half])
    states = {sfx: tracker.state.save(d / f"state{sfx}") for sfx in (".json", ".npz")}
    return {"day1": paths[0], "day2": paths[1], "state": states}


def _continue(cli, days, state: Path, *extra):
    """Run day 2 on ``state``; on failure the state and day 2 must be as they were."""
    before = _digest(state, days["day2"])
    r = cli("drift", days["day2"], *OPTS, "--state", state, *extra)
    if r.code != 0:
        assert _digest(state, days["day2"]) == before
    return r


# --------------------------------------------------------------------------- drift --state


def test_valid_states_continue(cli, days, tmp_path):
    for suffix, st in days["state"].items():
        s = tmp_path / f"s{suffix}"
        s.write_bytes(st.read_bytes())
        r = _continue(cli, days, s, "--json")
        assert r.code == 0, r.err
        assert json.loads(r.out)["state"]["how"] == "continued"


@pytest.mark.parametrize("edit", [
    # Was AttributeError (exit 1): a mapping replaced by a list, a string or null.
    lambda d: d.update(levels=None), lambda d: d.update(levels="x"), lambda d: d.update(references=[1, 2]),
    # Was filtered silently: a NaN or negative level, a NaN time.
    lambda d: d["levels"].update({k: -1.0 for k in d["levels"]}), lambda d: d.update(t_last=float("nan")),
    lambda d: d.update(n_samples=-5),
    # Finite, but its square is not: the next chunk came out with NaN uncertainties.
    lambda d: d["P"]["data"].__setitem__(0, 1e308),
])
def test_damaged_json_state(cli, days, tmp_path, edit):
    doc = json.loads(days["state"][".json"].read_text())
    edit(doc)
    s = tmp_path / "s.json"
    s.write_text(json.dumps(doc))
    _one_line(_continue(cli, days, s), "drift state")


@pytest.mark.parametrize("cut", [0, 300])
def test_empty_or_truncated_npz_state(cli, days, tmp_path, cut):
    # Was "internal error (Abort)" (EOFError) and BadZipFile.
    s = tmp_path / "s.npz"
    s.write_bytes(days["state"][".npz"].read_bytes()[:cut])
    _one_line(_continue(cli, days, s), "is not a drift state NPZ")


def test_state_written_by_another_command(cli, days, tmp_path):
    # A triaxial calibration file named as the state: said 'format_version 2', now says what it is.
    s = tmp_path / "params.json"
    s.write_text(json.dumps({"type": "senscal.triaxial", "format_version": 2, "params": {}}))
    _one_line(_continue(cli, days, s), "is a saved calibration")


def _stdin(monkeypatch, data: bytes):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data), encoding="utf-8"))


def test_binary_stdin(cli, tmp_path, monkeypatch):
    # Was UnicodeDecodeError (exit 1).
    _stdin(monkeypatch, b"\xff\xfe\x00\x01binary")
    _one_line(cli("drift", "-", *OPTS, "--state", tmp_path / "s.json"), "not UTF-8")
    assert not (tmp_path / "s.json").exists()


def test_stdin_first_chunk_too_small(cli, days, tmp_path, monkeypatch):
    _stdin(monkeypatch, days["day1"].read_bytes())
    _one_line(cli("drift", "-", *OPTS, "--state", tmp_path / "s.json", "--chunk-size", "3"), "--chunk-size")
    assert not (tmp_path / "s.json").exists()


# --------------------------------------------------------------------------- drift-fleet


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    _main("simulate", "fleet", "--out", d / "sim", "--seed", "1", "--channels", "4", "--samples", "120",
          "--channels-per-file", "2", "--rows-per-group", "60")
    data = d / "data"
    data.mkdir()
    for f in (d / "sim").glob("*.parquet"):
        (data / f.name).write_bytes(f.read_bytes())
    return {"dir": d, "data": data, "config": d / "sim" / "fleet.json"}


def _fleet(cli, fleet, data, config=None, *extra):
    config = config or fleet["config"]
    before = _digest(data, config)
    r = cli("drift-fleet", data, "--config", config, "--workers", "0", "--json", *extra)
    assert _digest(data, config) == before
    return r


def _parquet(tmp_path, fleet, edit) -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    df = pq.read_table(sorted(fleet["data"].glob("*.parquet"))[0]).to_pandas()
    d = tmp_path / "ds"
    d.mkdir()
    pq.write_table(pa.Table.from_pandas(edit(df), preserve_index=False), d / "a.parquet")
    return d


def _set_t_nan(df):
    df.loc[5, "t"] = np.nan
    return df


def _listcol(df):
    df[df.columns[1]] = [[1.0]] * len(df)
    return df


@pytest.mark.parametrize("edit, match", [
    (_set_t_nan, "finite"),                                               # was TypeError
    (_listcol, "type list"),                                              # was ValueError
    (lambda df: df.assign(t=df["t"].astype("datetime64[s]")), "type timestamp"),   # was read as seconds
])
def test_fleet_bad_parquet(cli, fleet, tmp_path, edit, match):
    _one_line(_fleet(cli, fleet, _parquet(tmp_path, fleet, edit)), match)


def test_fleet_file_without_rows(cli, fleet, tmp_path):
    # Was IndexError: a file with the schema but no rows is nothing to filter.
    r = _fleet(cli, fleet, _parquet(tmp_path, fleet, lambda df: df.iloc[:0]))
    assert r.code == 0, r.err


@pytest.mark.parametrize("edit, match", [
    (lambda g: g.update(channels=5), "channels must be"),                 # was TypeError
    (lambda g: g.update(channel_levels=3), "channel_levels must be"),    # was AttributeError
    (lambda g: g["levels"].update(y_noise_std=1e200), "noise level"),     # was OverflowError
    (lambda g: g.update(name=[1]), "name must be a text"),                # was accepted as "[1]"
])
def test_fleet_bad_config(cli, fleet, tmp_path, edit, match):
    doc = json.loads(fleet["config"].read_text())
    edit(doc["groups"][0])
    c = tmp_path / "c.json"
    c.write_text(json.dumps(doc))
    _one_line(_fleet(cli, fleet, fleet["data"], c), match)


def test_fleet_unknown_top_level_key(cli, fleet, tmp_path):
    c = tmp_path / "c.json"
    c.write_text(json.dumps({**json.loads(fleet["config"].read_text()), "group": []}))
    _one_line(_fleet(cli, fleet, fleet["data"], c), "unknown top-level keys")


@pytest.mark.parametrize("opt", ["--state", "--out"])
def test_fleet_output_inside_the_dataset(cli, fleet, opt):
    # Wrote NPZ / Parquet files into the input folder (the next run read its own output as data).
    _one_line(_fleet(cli, fleet, fleet["data"], None, opt, fleet["data"] / "sub"), "inside the dataset")
    assert not (fleet["data"] / "sub").exists()


@pytest.fixture(scope="module")
def store(fleet, tmp_path_factory):
    s = tmp_path_factory.mktemp("store") / "st"
    _main("drift-fleet", fleet["data"], "--config", fleet["config"], "--workers", "0", "--state", s)
    return s


def _damage(store: Path, tmp_path: Path, edit) -> Path:
    s = tmp_path / "st"
    s.mkdir()
    for f in store.iterdir():
        (s / f.name).write_bytes(f.read_bytes())
    edit(s, sorted(s.glob("*.npz"))[0])
    return s


def _npz_with(f: Path, **arrays):
    z = dict(np.load(f))
    z.update(arrays)
    np.savez(f, **z)


@pytest.mark.parametrize("edit, match", [
    (lambda s, f: f.write_bytes(b""), "cannot be read"),                                # was Abort (EOFError)
    (lambda s, f: f.write_bytes(f.read_bytes()[:200]), "cannot be read"),              # was BadZipFile
    (lambda s, f: _npz_with(f, format_version=np.zeros(3)), "cannot be read"),         # was TypeError
    (lambda s, f: _npz_with(f, channels=np.zeros(7)), "is damaged"),                   # was IndexError
    (lambda s, f: _npz_with(f, t_last=np.full(2, np.nan)), "is damaged"),              # skipped every row
    (lambda s, f: _npz_with(f, n_samples=np.full(2, np.nan)), "is damaged"),           # was ValueError
    (lambda s, f: (s / "store.json").write_text(json.dumps({"format_version": 1, "groups": "x"})), "damaged"),
])
def test_fleet_damaged_store(cli, fleet, store, tmp_path, edit, match):
    s = _damage(store, tmp_path, edit)
    before = _digest(s)
    _one_line(_fleet(cli, fleet, fleet["data"], None, "--state", s), match)
    assert _digest(s) == before


@pytest.mark.parametrize("out", ["o.json", "state.json", "folder"])
def test_bad_out_leaves_the_state(cli, days, tmp_path, out):
    # The state was saved before --out failed: the next run refused the same file ('time going backwards')
    # and the corrected values of this one were never written.
    s = tmp_path / "state.json"
    s.write_bytes(days["state"][".json"].read_bytes())
    (tmp_path / "folder").mkdir()
    _one_line(_continue(cli, days, s, "--out", tmp_path / out), "--out")
    assert _continue(cli, days, s, "--out", tmp_path / "ok.csv").code == 0


def test_fleet_channel_without_data_is_named(cli, fleet, tmp_path):
    # Reported its prior (bias 0, u the prior width) as if measured, without a word.
    def blind(df):
        df[df.columns[1]] = np.nan
        return df

    data = _parquet(tmp_path, fleet, blind)
    r = _fleet(cli, fleet, data)
    assert r.code == 0, r.err
    assert any(w.startswith("fleet-channel-no-data") for w in json.loads(r.out)["warnings"]), r.out
    assert _fleet(cli, fleet, data, None, "--strict").code == 3
