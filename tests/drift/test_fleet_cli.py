"""``senscal drift-fleet`` and ``senscal simulate fleet`` end to end (in process: --workers 0)."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pyarrow.parquet as pq


def _digest(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_two_days_json_table_strict_and_inputs_untouched(cli, tmp_path):
    data = tmp_path / "fleet"
    r = cli("simulate", "fleet", "--out", data, "--seed", "2", "--channels", "6", "--samples", "600", "--segments", "2",
            "--channels-per-file", "3", "--rows-per-group", "100", "--kind", "covariate")
    assert r.code == 0, r.err
    truth = json.loads((data / "fleet_truth.json").read_text())
    before = _digest(data)
    cfg = data / "fleet.json"
    r = cli("drift-fleet", data / "seg-000", "--config", cfg, "--state", tmp_path / "st", "--workers", "0")
    assert r.code == 0, r.err
    assert "largest biases" in r.out and "6 channels" in r.out
    r = cli("drift-fleet", data / "seg-001", "--config", cfg, "--state", tmp_path / "st", "--workers", "0",
            "--out", tmp_path / "corr", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["n_channels"] == 6 and doc["n_samples"] == 6 * 300 and doc["n_skipped"] == 0
    assert doc["shared_chunks"] == 0 and doc["chunks"] == 2 * 3   # covariates: per-channel covariances
    ch = doc["channels"]["s00004"]
    assert ch["t_last"] == 599.0 and ch["u_bias"] > 0 and ch["group"] == "covariate"
    # The stated u is not far too small against the simulated truth (covariate bias at the last sample).
    z = [(doc["channels"][c]["bias"] - truth["final_bias"][c]) / doc["channels"][c]["u_bias"] for c in doc["channels"]]
    assert np.max(np.abs(z)) < 5
    # Corrected data: t, each channel and its u, the second day only.
    files = sorted((tmp_path / "corr").rglob("*.parquet"))
    tb = pq.read_table(files[0])
    assert tb.column_names[:3] == ["t", "s00000", "s00000.u_bias"] and tb.column("t").to_numpy()[0] == 300.0
    assert sum(pq.read_metadata(f).num_rows for f in files) == 2 * 300
    # Running the same day again: nothing new, a named warning; --strict turns it into exit 3.
    r = cli("drift-fleet", data / "seg-001", "--config", cfg, "--state", tmp_path / "st", "--workers", "0", "--strict")
    assert r.code == 3 and "fleet-rows-skipped" in r.err
    assert _digest(data) == before


def test_bad_input_one_line_exit_2(cli, tmp_path):
    data = tmp_path / "fleet"
    assert cli("simulate", "fleet", "--out", data, "--channels", "2", "--samples", "50", "--rows-per-group", "20").code == 0
    cfg = data / "fleet.json"
    r = cli("drift-fleet", tmp_path / "nope", "--config", cfg, "--workers", "0")
    assert r.code == 2 and "does not exist" in r.err and len(r.err.strip().splitlines()) == 1
    bad = tmp_path / "bad.yaml"
    bad.write_text("groups:\n  - name: g\n    setup: {preset: known}\n    levels: {y_noise_std: 0.1}\n")
    r = cli("drift-fleet", data, "--config", bad, "--workers", "0")
    assert r.code == 2 and "needs the noise levels ['y_bias_rate_std']" in r.err
    other = tmp_path / "other.json"
    doc = json.loads(cfg.read_text())
    doc["groups"][0]["levels"]["y_noise_std"] = 0.5
    other.write_text(json.dumps(doc))
    assert cli("drift-fleet", data, "--config", cfg, "--state", tmp_path / "s", "--workers", "0").code == 0
    r = cli("drift-fleet", data, "--config", other, "--state", tmp_path / "s", "--workers", "0")
    assert r.code == 2 and "another set-up, levels or prior" in r.err
    r = cli("drift-fleet", data, "--config", cfg, "--workers", "-1")
    assert r.code == 2 and "workers" in r.err
