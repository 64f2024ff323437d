"""The ``drift`` job (issue 18 item 4): one document for the CLI and the API, quantities, a Recording source."""

from __future__ import annotations

import json

import pytest

from senscal import jobs
from senscal.errors import InputError
from senscal.jobs.drift import DriftOptions, drift


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.io import write_recording
    from senscal.simulate.drift import simulate_drift

    d = tmp_path_factory.mktemp("job")
    rec, _ = simulate_drift(days=2.0, dt=900.0, seed=5)
    write_recording(rec, d / "drift.csv")
    return d / "drift.csv", rec


OPTS = DriftOptions(preset="redundant", channels=("ref", "drift", "thermal"), trusted=("ref",), covariate="temperature",
                    covariate_reference=20.0, compare=False)


def test_api_document_is_the_cli_document(sim, cli):
    path, _ = sim
    r = cli("drift", path, "--preset", "redundant", "--channels", "ref,drift,thermal", "--trusted", "ref",
            "--covariate", "temperature", "--covariate-reference", "20", "--no-compare", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out) == json.loads(json.dumps(jobs.run("drift", str(path), OPTS).to_dict()))


def test_quantities_are_the_final_biases(sim):
    path, rec = sim
    res = drift(rec, OPTS)  # a Recording in memory works as the file does
    doc = res.to_dict()
    q = {x.name: x for x in res.quantities()}
    assert set(q) == {"drift.bias", "thermal.bias"}
    for c in ("drift", "thermal"):
        assert q[f"{c}.bias"].value == doc["channels"][c]["bias"]
        assert q[f"{c}.bias"].uncertainty == doc["channels"][c]["bias_std"] > 0
    df = res.to_dataframe()
    assert list(df["channel"]) == ["drift", "thermal"] and (df["U"] == 2 * df["u"]).all()


def test_state_job_returns_the_state_and_does_not_write_it(sim, tmp_path):
    path, _ = sim
    state = tmp_path / "s.json"
    res = drift(path, DriftOptions(**{**OPTS.__dict__, "state": str(state), "window": 4}))
    assert not state.exists() and res.state is not None and res.document["state"]["how"] == "started"
    assert res.output.t.size == res.state.n_samples - 4


@pytest.mark.parametrize("kw, words", [(dict(preset="nope"), "--preset"), (dict(window=3, smooth=True), "either"),
                                       (dict(fit_levels=True), "--state runs"),
                                       (dict(state="s.json", smooth=True), "cannot continue")])
def test_bad_options_are_one_line_errors(kw, words):
    with pytest.raises(InputError, match=words):
        DriftOptions(**kw)
