"""Structured side documents, mutated (hypothesis): a drift tracker state, a fleet configuration, a lab profile.

A valid document is edited one to three times at random places (a field
deleted, replaced by a hostile value -- null, a list, a mapping, NaN, 1e308,
a negative number, a huge or control-character string, markup -- or an
unknown field added) and handed to the API that reads it.  Whatever the
edit, the reader and everything downstream of it (the tracker's next chunk,
the fleet run, the HTML certificate and the DCC) either work or raise a
:class:`senscal.errors.SenscalError` subclass with a one-line message: never
KeyError/TypeError/AttributeError, never a NaN or negative uncertainty.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _fuzz_harness import LONG
from senscal.errors import SenscalError

HOSTILE_VALUES = [None, True, 0, -1, -1.0, 1e308, -1e308, float("nan"), float("inf"), "", "abc", "x" * 20000,
                  "\x00\x1b[31m\x07", "[/bold]<b>&</b>]]>", [], {}, [[1, 2], [3]], [1.0, 2.0, 3.0], {"a": 1},
                  {"shape": [2, 2], "data": [1, 2]}, {"shape": [-1], "data": []}, "2026-13-45"]

EXAMPLES = 300 if LONG else 25
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


def _paths(doc, prefix=()):
    """Every place in a JSON-like tree (mapping keys and list indices), parents before children."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        out.append(prefix + (k,))
        out.extend(_paths(v, prefix + (k,)))
    return out


def mutate_doc(data, doc):
    """One to three random edits of a JSON-like document (a deep copy)."""
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        paths = _paths(doc)
        if not paths:
            break
        path = data.draw(st.sampled_from(paths), label="where")
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        op = data.draw(st.sampled_from(["replace", "replace", "delete", "add"]), label="op")
        if op == "delete":
            del parent[path[-1]]
        elif op == "add" and isinstance(parent, dict):
            parent[data.draw(st.sampled_from(["extra", "Name", "levels ", "0"]))] = 1
        else:
            parent[path[-1]] = copy.deepcopy(data.draw(st.sampled_from(HOSTILE_VALUES), label="value"))
    return doc


def _one_line(exc: BaseException) -> None:
    assert isinstance(exc, SenscalError), f"{type(exc).__name__}: {exc}"
    assert "\n" not in str(exc).strip(), str(exc)


# --------------------------------------------------------------------------- drift tracker state


DRIFT_OPTS = ["--preset", "redundant", "--trusted", "a", "--channels", "a,b", "--window", "3", "--no-compare"]


@pytest.fixture(scope="module")
def tracker_files(tmp_path_factory):
    """The state ``senscal drift day1.csv DRIFT_OPTS --state`` leaves (known levels: no search), and day 2."""
    from senscal.drift.stream import DriftTracker
    from senscal.io import Recording, write_recording
    from senscal.jobs.drift import DriftOptions, drift_setup_for

    d = tmp_path_factory.mktemp("tracker")
    rng = np.random.default_rng(0)
    y = rng.normal(0, 0.05, (2, 80))
    rec = Recording({"a": y[0], "b": y[1]}, t=np.arange(80.0))
    setup = drift_setup_for(rec, DriftOptions(preset="redundant", trusted=("a",), channels=("a", "b"), window=3))
    tr = DriftTracker(setup, {k: 0.05 if k.endswith("noise_std") else 0.01 for k in setup.level_names()}, lag=3)
    tr.update(y[:, :40], rec.time[:40])
    day2 = write_recording(Recording({"a": y[0, 40:], "b": y[1, 40:]}, t=rec.time[40:]), d / "day2.csv")
    return {"doc": tr.state.to_dict(), "json": tr.state.save(d / "s.json"), "npz": tr.state.save(d / "s.npz"),
            "day2": day2}


@pytest.fixture(scope="module")
def tracker_doc(tracker_files):
    return tracker_files["doc"]


@SETTINGS
@given(data=st.data())
def test_mutated_tracker_state(tracker_doc, data):
    from senscal.drift.stream import DriftTracker, TrackerState

    doc = mutate_doc(data, tracker_doc)
    try:
        state = TrackerState.from_dict(json.loads(json.dumps(doc)), source="drift state s.json")
        tr = DriftTracker.from_state(state)
        t0 = 1.0 + (state.t_last if state.t_last is not None else 0.0)
        out = tr.update(np.zeros((2, 10)), t0 + np.arange(10.0))
    except Exception as exc:  # noqa: BLE001 - the point: which exception
        _one_line(exc)
        return
    u = np.asarray(out.u_bias)
    assert np.all(np.isfinite(u)) and np.all(u >= 0), u


# --------------------------------------------------------------------------- fleet configuration


@pytest.fixture(scope="module")
def fleet_dataset(tmp_path_factory):
    from senscal.simulate.fleet import simulate_fleet

    d = tmp_path_factory.mktemp("fleetdoc")
    simulate_fleet(d / "sim", n_channels=3, n_samples=60, fs=1.0, kind="covariate", segments=1,
                   channels_per_file=3, rows_per_group=30, missing=0.0, seed=1)
    return d / "sim"


@SETTINGS
@given(data=st.data())
def test_mutated_fleet_config(fleet_dataset, tmp_path_factory, data):
    from senscal.drift.fleet import load_fleet_config, run_fleet

    doc = mutate_doc(data, json.loads((fleet_dataset / "fleet.json").read_text()))
    d = tmp_path_factory.mktemp("cfg")
    cfg = d / "fleet.yaml"
    cfg.write_text(yaml.safe_dump(doc, allow_unicode=True))
    try:
        groups = load_fleet_config(cfg)
        res = run_fleet(fleet_dataset, groups, state=d / "state")
    except Exception as exc:  # noqa: BLE001
        _one_line(exc)
        return
    u = np.asarray(res.u_bias)
    assert np.all(np.isnan(u) | (u >= 0)), u
    assert not np.any(np.isinf(u)), u


# --------------------------------------------------------------------------- lab profile


LAB = {
    "name": "Vibration Laboratory Nord", "address": "Hafenstrasse 7, 20457 Hamburg, Germany", "country": "DE",
    "email": "lab@example.org", "accreditation": "DAkkS D-K-99999-01-00", "procedure": "QP-VIB-07 rev 3",
    "approvers": [{"name": "Dr. Ada Pruefer", "role": "Head of laboratory"}],
    "standards": [{"name": "Reference accelerometer", "serial": "RS-1", "certificate": "PTB-1.21-4711",
                   "traceability": "PTB Braunschweig", "due": "2027-03-01", "u_relative": 0.0005}],
    "run": {"location": "hall 2", "customer": "ACME", "customer_address": "Am Markt 1", "customer_email": "qa@acme.example",
            "item": "velocity sensor", "manufacturer": "Qfab", "model": "QV-1", "serial": "SN-1",
            "calibration_date": "2026-01-05", "issue_date": "2026-01-06",
            "conditions": [{"name": "temperature", "value": 23.1, "u": 0.5, "unit": "degC"}]},
}


@pytest.fixture(scope="module")
def velocity():
    from senscal.simulate.vibration import simulate_hydraulic
    from senscal.vibration import velocity_calibration, velocity_point

    recs, _ = simulate_hydraulic(frequencies=(2.0, 3.5), periods=4.3, min_duration=2.0, seed=1)
    return velocity_calibration([velocity_point(r["position"], r["velocity"], r.time) for r in recs], unit="V/(m/s)")


@settings(SETTINGS, max_examples=200 if LONG else 8)  # each example renders a certificate and validates a DCC
@given(data=st.data())
def test_mutated_lab_profile(velocity, tmp_path_factory, data):
    from senscal.report.certificate import certificate_html
    from senscal.report.dcc import dcc_xml
    from senscal.report.lab import CertificateInfo, load_lab_profile

    doc = mutate_doc(data, LAB)
    p = tmp_path_factory.mktemp("lab") / "lab.yaml"
    p.write_text(yaml.safe_dump(doc, allow_unicode=True))
    try:
        lab, run = load_lab_profile(p)
        info = CertificateInfo(lab, run)
        html = certificate_html("velocity", velocity, info=info, unit="V/(m/s)", method="sine fit")
        dcc_xml("velocity", velocity, info, unit="V/(m/s)")
    except Exception as exc:  # noqa: BLE001
        _one_line(exc)
        return
    for s in info.lab.standards:
        assert s.u_relative is None or math.isfinite(s.u_relative) and s.u_relative >= 0
    for c in info.run.conditions:
        assert math.isfinite(c.value) and (c.u is None or math.isfinite(c.u) and c.u >= 0)
    assert "<b>&</b>" not in html  # markup in a field is escaped, never rendered


# --------------------------------------------------------------------------- the same files, byte-mutated, on the CLI


@pytest.mark.parametrize("kind", ["json", "npz"])
def test_mutated_state_file_cli(cli, tracker_files, tmp_path, kind):
    """``senscal drift day2.csv --state S`` on a byte-mutated S: a result or one line; a failed run leaves S as it was."""
    from _fuzz_harness import CASE_TIMEOUT_S, CASES_PER_TARGET, TALLY, mutate, run_case

    data = tracker_files[kind].read_bytes()
    (tmp_path / f"ok.{kind}").write_bytes(data)
    # The seed continues (else the cases would only exercise the first error).
    assert cli("drift", tracker_files["day2"], *DRIFT_OPTS, "--state", tmp_path / f"ok.{kind}").code == 0
    rng = np.random.default_rng(7 if kind == "json" else 8)
    failures = []
    for i in range(CASES_PER_TARGET):
        s = tmp_path / f"case{i}.{kind}"
        s.write_bytes(mutate(data, rng))
        before = s.read_bytes()
        r_kind, detail = run_case(cli, ["drift", str(tracker_files["day2"]), *DRIFT_OPTS, "--state", str(s)],
                                  [tracker_files["day2"]], CASE_TIMEOUT_S)
        if r_kind == "clean" and s.read_bytes() != before:
            r_kind, detail = "modified", f"a refused state was changed: case {i}"
        TALLY.add(f"drift --state .{kind}", r_kind, detail)
        if detail is not None:
            failures.append(detail)
    assert not failures, failures[:3]


def test_mutated_fleet_config_cli(cli, fleet_dataset, tmp_path):
    from _fuzz_harness import CASE_TIMEOUT_S, CASES_PER_TARGET, TALLY, mutate, run_case

    data = (fleet_dataset / "fleet.json").read_bytes()
    rng = np.random.default_rng(9)
    failures = []
    for i in range(CASES_PER_TARGET):
        c = tmp_path / f"case{i}.json"
        c.write_bytes(mutate(data, rng))
        r_kind, detail = run_case(cli, ["drift-fleet", str(fleet_dataset), "--config", str(c), "--workers", "0",
                                        "--state", str(tmp_path / f"st{i}"), "--json"], [c], CASE_TIMEOUT_S)
        TALLY.add("drift-fleet --config", r_kind, detail)
        if detail is not None:
            failures.append(detail)
    assert not failures, failures[:3]


def test_mutated_fleet_parquet_cli(cli, fleet_dataset, tmp_path):
    """A byte-mutated Parquet file of the dataset (a damaged page was 'internal error (OSError: thrift ...)')."""
    from _fuzz_harness import CASE_TIMEOUT_S, CASES_PER_TARGET, TALLY, mutate, run_case

    data = next(fleet_dataset.glob("*.parquet")).read_bytes()
    rng = np.random.default_rng(10)
    failures = []
    for i in range(CASES_PER_TARGET // 2):  # half a target's cases: each reads a whole (small) dataset
        ds = tmp_path / f"ds{i}"
        ds.mkdir()
        (ds / "a.parquet").write_bytes(mutate(data, rng))
        r_kind, detail = run_case(cli, ["drift-fleet", str(ds), "--config", str(fleet_dataset / "fleet.json"),
                                        "--workers", "0", "--json"], [ds / "a.parquet"], CASE_TIMEOUT_S)
        TALLY.add("drift-fleet DATASET", r_kind, detail)
        if detail is not None:
            failures.append(detail)
    assert not failures, failures[:3]
