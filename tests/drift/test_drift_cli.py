"""``senscal drift`` and ``senscal simulate drift`` end to end."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from senscal.io import read_recording


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.drift import simulate_drift

    d = tmp_path_factory.mktemp("drift")
    rec, truth = simulate_drift(days=5.0, dt=900.0, seed=4)
    write_recording(rec, d / "drift.csv")
    write_truth(truth, d / "drift_truth.json")
    return d


def test_simulate_writes_recording_and_truth(cli, tmp_path):
    r = cli("simulate", "drift", "--out", tmp_path, "--seed", "1", "--days", "2", "--dt", "600")
    assert r.code == 0, r.err
    rec = read_recording(tmp_path / "drift.csv")
    assert rec.names == ["ref", "drift", "thermal", "temperature"]
    truth = json.loads((tmp_path / "drift_truth.json").read_text())
    assert len(truth["signal"]) == rec.n_samples and truth["ramp_channel"] == "drift"
    assert cli("simulate", "drift", "--out", tmp_path, "--days", "-1").code == 2


def test_redundant_preset_csv_json_plot(cli, sim, tmp_path):
    out, png = tmp_path / "out.csv", tmp_path / "drift.png"
    before = (sim / "drift.csv").read_bytes()
    r = cli("drift", sim / "drift.csv", "--preset", "redundant", "--channels", "ref,drift,thermal", "--trusted", "ref",
            "--covariate", "temperature", "--out", out, "--plot", png, "--json", "--no-compare")
    assert r.code == 0, r.err
    assert (sim / "drift.csv").read_bytes() == before  # input untouched
    doc = json.loads(r.out)
    assert set(doc["channels"]) == {"drift", "thermal"}
    for c in ("drift", "thermal"):
        d = doc["channels"][c]
        assert {"bias", "bias_std", "onset_t"} <= set(d) and d["bias_std"] > 0
    assert doc["channels"]["drift"]["onset_t"] is not None
    truth = json.loads((sim / "drift_truth.json").read_text())
    assert abs(doc["channels"]["drift"]["bias"] - truth["bias_drift"][-1]) < 4 * doc["channels"]["drift"]["bias_std"]
    assert doc["noise"]["drift_noise_std"]["estimated"] is True and doc["noise"]["drift_noise_std"]["std"] > 0
    df = pd.read_csv(out)
    assert list(df.columns) == ["t", "drift_corrected", "drift_bias", "drift_bias_std",
                                "thermal_corrected", "thermal_bias", "thermal_bias_std"]
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_human_output_shows_expanded_uncertainty(cli, sim):
    r = cli("drift", sim / "drift.csv", "--preset", "covariate", "--channels", "thermal", "--covariate", "temperature",
            "--smooth", "--no-compare")
    assert r.code == 0, r.err
    assert "k=2" in r.out and "thermal_temperature_coefficient" in r.out and "smoother" in r.out


def test_model_preset_from_yaml(cli, sim, tmp_path):
    y = tmp_path / "m.yaml"
    y.write_text(
        "channels: [ref, drift]\n"
        "trusted: [ref]\n"
        "signal: {kind: random_walk, level: 6.0e-4}\n"
        "noise_std: {ref: 0.05, drift: 0.05}\n"
        "biases:\n"
        "  - {channel: drift, dynamics: random_walk, level: 3.0e-4}\n")
    out = tmp_path / "o.csv"
    r = cli("drift", sim / "drift.csv", "--preset", "model", "--model", y, "--window", "8", "--out", out, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["method"] == "window" and doc["window"] == 8
    assert all(not v["estimated"] for v in doc["noise"].values())
    assert list(pd.read_csv(out).columns) == ["t", "drift_corrected", "drift_bias", "drift_bias_std"]


@pytest.mark.parametrize("args, words", [
    (["--preset", "redundant"], "unobservable"),
    (["--preset", "redundant", "--trusted", "nosuch"], "nosuch"),
    (["--preset", "covariate", "--channels", "thermal"], "--covariate"),
    (["--preset", "covariate", "--covariate", "temperature"], "one sensor"),
    (["--preset", "redundant", "--trusted", "ref", "--window", "5", "--smooth"], "either"),
    (["--preset", "model"], "--model"),
    (["--preset", "bogus"], "--preset"),
    (["--preset", "covariate", "--channels", "thermal", "--covariate", "temperature", "--bias-dynamics", "ramp"],
     "--bias-dynamics"),
    (["--preset", "known", "--true-value", "nan"], "finite"),
    (["--preset", "redundant", "--channels", "ref,nope", "--trusted", "ref"], "nope"),
])
def test_user_errors_exit_2_with_one_line(cli, sim, args, words):
    r = cli("drift", sim / "drift.csv", *args)
    assert r.code == 2
    assert words in r.err and "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1


def test_unobservable_message_names_biases(cli, sim):
    r = cli("drift", sim / "drift.csv", "--preset", "redundant", "--channels", "ref,drift,thermal")
    assert r.code == 2
    for word in ("ref_bias", "drift_bias", "thermal_bias", "trusted", "covariate"):
        assert word in r.err


def test_bad_yaml_is_a_file_format_error(cli, sim, tmp_path):
    y = tmp_path / "bad.yaml"
    y.write_text("channels: [ref]\nfoo: 1\n")
    r = cli("drift", sim / "drift.csv", "--preset", "model", "--model", y)
    assert r.code == 2 and "unknown keys" in r.err


def test_simulate_layouts_and_strict_exit_3(cli, tmp_path):
    r = cli("simulate", "drift", "--out", tmp_path, "--layout", "pair", "--dt", "1", "--samples", "500",
            "--signal-tau", "200", "--bias", "ramp", "--ramp-start-s", "150", "--ramp-slope", "0.006", "--seed", "2")
    assert r.code == 0, r.err
    rec = read_recording(tmp_path / "drift.csv")
    assert rec.names == ["s1", "s2"] and rec.n_samples == 500
    # Random-walk bias on a ramp: the ramp wins on AIC.  The job uses it when the random walk's innovations are
    # rejected (and says so); otherwise it names it, and --strict exits 3.  Never the random walk in silence.
    r = cli("drift", tmp_path / "drift.csv", "--preset", "redundant", "--trusted", "s1", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert [c["model"] for c in doc["model_comparison"]][:2] == ["asked", "--bias-dynamics ramp"]
    if doc["model_selected"] == "--bias-dynamics ramp":
        assert doc["warnings"] == []
    else:
        assert "better-model" in r.err and doc["model_check"]["adequate"]
        assert cli("drift", tmp_path / "drift.csv", "--preset", "redundant", "--trusted", "s1", "--strict").code == 3
    r = cli("drift", tmp_path / "drift.csv", "--preset", "redundant", "--trusted", "s1", "--bias-dynamics", "ramp",
            "--json", "--strict")
    assert r.code == 0, r.err
    assert "s2_bias_slope" in json.loads(r.out)["channels"]["s2"]["terms"]


@pytest.mark.parametrize("args, words", [
    (["--layout", "nope"], "--layout"),
    (["--layout", "pair", "--bias", "sine"], "--bias"),
    (["--layout", "pair", "--samples", "3"], "--samples"),
    (["--layout", "pair", "--signal-tau", "-1"], "--signal-tau"),
])
def test_simulate_bad_options_exit_2(cli, tmp_path, args, words):
    r = cli("simulate", "drift", "--out", tmp_path, *args)
    assert r.code == 2 and words in r.err and len(r.err.strip().splitlines()) == 1


def test_drift_bad_bias_dynamics_and_known_with_trusted(cli, sim):
    r = cli("drift", sim / "drift.csv", "--preset", "redundant", "--trusted", "ref", "--bias-dynamics", "sine")
    assert r.code == 2 and "--bias-dynamics" in r.err
    r = cli("drift", sim / "drift.csv", "--preset", "known", "--trusted", "ref")
    assert r.code == 2 and "--trusted" in r.err
