"""``senscal registry ...`` and ``senscal fit --save`` from the command line."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest


def _ok(r):
    assert r.code == 0, r.err
    return r


def _one_line_error(r, *fragments):
    assert r.code == 2, (r.out, r.err)
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("senscal: error:"), r.err
    assert "Traceback" not in r.err
    for f in fragments:
        assert f in lines[0], lines[0]
    return lines[0]


def _history_cli(cli, db, serial="A1", values=(0.01000, 0.01004, 0.01008, 0.01012), u2=2e-6):
    _ok(cli("registry", "add", serial, "--kind", "accelerometer", "--model", "4371",
            "--nominal", "sensitivity=0.01 V/(m/s^2)", "--db", db))
    for year, v in zip(range(2020, 2020 + len(values)), values):
        _ok(cli("registry", "record", serial, "--quantity", "sensitivity", "--value", v, "--uncertainty", u2,
                "--k", "2", "--unit", "V/(m/s^2)", "--date", f"{year}-03-01", "--note", f"cert {year}", "--db", db))


def test_record_history_due_json(cli, db_url, tmp_path):
    _history_cli(cli, db_url)
    sens = json.loads(_ok(cli("registry", "sensors", "--db", db_url, "--json")).out)
    assert [(s["serial"], s["n_calibrations"]) for s in sens["sensors"]] == [("A1", 4)]
    hist = json.loads(_ok(cli("registry", "history", "A1", "--quantity", "sensitivity", "--json", "--db", db_url)).out)
    recs = hist["records"]
    assert [r["value"] for r in recs] == [0.01000, 0.01004, 0.01008, 0.01012]
    # --uncertainty is quoted with --k 2: the registry keeps the standard uncertainty.
    assert all(r["uncertainty"] == pytest.approx(1e-6) and r["k"] == 2 for r in recs)
    assert {"date", "quantity", "value", "uncertainty", "unit"} <= set(recs[0])
    png = tmp_path / "hist.png"
    _ok(cli("registry", "history", "A1", "--quantity", "sensitivity", "--plot", png, "--db", db_url))
    assert png.stat().st_size > 5000
    due = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "2%",
                             "--as-of", "2023-06-01", "--json", "--db", db_url)).out)
    # Exactly +4e-5 per year (records one year apart, differences in leap days aside).
    assert due["drift_per_year"] == pytest.approx(4e-5, rel=2e-3)
    assert due["significant"] is True
    assert due["u_drift_per_year"] == pytest.approx(1e-6 / np.sqrt(5.0), rel=2e-3)  # 1/sqrt(sum (t - tbar)^2)
    # The noiseless line leaves 2 % of 0.0100 five years after the first record (2025-03-01); adding the
    # k=2 uncertainty of the extrapolated line makes it earlier, but after the last record.
    assert "2023-03-01" < due["due_date"] < "2025-03-01" and due["overdue"] is False
    assert due["as_of"].startswith("2023-06-01")
    # Judged today (after 2025-03-01) the same due date has passed: overdue, in JSON and in the table.
    now = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "2%",
                             "--json", "--db", db_url)).out)
    assert now["due_date"] == due["due_date"] and now["overdue"] is True
    r = _ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "2%", "--db", db_url))
    assert "OVERDUE" in r.out and "overdue" in r.err
    r = _ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "2%", "--as-of", "2023-06-01",
                "--db", db_url))
    assert "OVERDUE" not in r.out and "overdue" not in r.err
    assert abs(due["deviation_at_due"]) + 2 * due["u_deviation_at_due"] == pytest.approx(2e-4, rel=1e-5)
    late = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "1%",
                              "--json", "--db", db_url)).out)
    assert late["overdue"] is True and late["due_date"].startswith("2023-03-01")
    nominal = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "0.02",
                                 "--nominal", "0.0099", "--json", "--db", db_url)).out)
    assert nominal["reference"] == 0.0099 and nominal["tolerance"] == pytest.approx(0.02 * 0.0099)
    table = _ok(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "1%", "--db", db_url)).out
    assert "drift per year" in table and "due date" in table


def test_user_errors_are_one_line(cli, db_url, tmp_path):
    _history_cli(cli, db_url, values=(0.01,))
    _one_line_error(cli("registry", "add", "A1", "--kind", "accelerometer", "--db", db_url), "already registered")
    _one_line_error(cli("registry", "history", "B2", "--db", db_url), "unknown sensor serial 'B2'")
    _one_line_error(cli("registry", "record", "B2", "--quantity", "s", "--value", "1", "--uncertainty", "0.1", "--k", "2",
                        "--unit", "V", "--date", "2024-01-01", "--db", db_url), "unknown sensor serial")
    _one_line_error(cli("registry", "due", "A1", "--quantity", "phase", "--tolerance", "1%", "--db", db_url),
                    "no recorded quantity 'phase'")
    _one_line_error(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "1%", "--db", db_url),
                    "1 record", "at least two")
    _one_line_error(cli("registry", "record", "A1", "--quantity", "s", "--value", "1", "--uncertainty", "0.1", "--k", "2",
                        "--unit", "V", "--date", "first of May", "--db", db_url), "ISO 8601")
    _one_line_error(cli("registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "lots", "--db", db_url),
                    "--tolerance")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    _one_line_error(cli("registry", "import", bad, "--db", db_url), "not valid JSON")
    bad.write_text('{"format": "something else"}')
    _one_line_error(cli("registry", "import", bad, "--db", db_url), "not a senscal registry export")


def test_malformed_and_unreachable_urls_mask_password(cli):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    line = _one_line_error(cli("registry", "sensors", "--db", f"postgresql://lab:TopSecret1@127.0.0.1:{port}/r"),
                           "cannot reach", "lab:***@")
    assert "TopSecret1" not in line
    line = _one_line_error(cli("registry", "sensors", "--db", "postgresql://lab:TopSecret1@h:port:x/r"),
                           "malformed database URL")
    assert "TopSecret1" not in line


def test_export_import_cli_round_trip(cli, db_url, tmp_path):
    _history_cli(cli, db_url)
    out1, out2 = tmp_path / "a.json", tmp_path / "b.json"
    _ok(cli("registry", "export", out1, "--db", db_url))
    empty = f"sqlite:///{tmp_path / 'empty.sqlite'}"
    added = json.loads(_ok(cli("registry", "import", out1, "--db", empty, "--json")).out)
    assert added == {"sensors": 1, "calibrations": 4, "skipped": 0}
    _ok(cli("registry", "export", out2, "--db", empty))
    assert out1.read_text() == out2.read_text()


def test_fit_save_records_the_result(cli, tmp_path):
    from senscal.io import write_recording
    from senscal.simulate.sine import simulate_sine

    rec, truth = simulate_sine(n_channels=2, fs=1000.0, duration=1.0, frequency=12.5, noise=0.05, seed=4)
    path = tmp_path / "sine.csv"
    write_recording(rec, path)
    before = path.read_bytes()
    db = f"sqlite:///{tmp_path / 'reg.sqlite'}"
    # A --db file that does not exist is refused (a typo must not start a new registry) unless the
    # command registers the sensor (--create-sensor).
    r = _one_line_error(cli("fit", path, "--save", "--sensor", "V7", "--db", db), "reg.sqlite does not exist",
                        "--create-sensor")
    assert not (tmp_path / "reg.sqlite").exists()
    _one_line_error(cli("fit", path, "--sensor", "V7"), "add --save")
    _one_line_error(cli("fit", path, "--save"), "--save needs --sensor")
    r = _ok(cli("fit", path, "--json", "--save", "--sensor", "V7", "--create-sensor", "velocity sensor", "--db", db,
                "--date", "2024-05-01T10:00+02:00"))
    doc = json.loads(r.out)  # stdout stays pure JSON; the confirmation is on stderr
    assert "saved calibration" in r.err and "V7" in r.err
    hist = json.loads(_ok(cli("registry", "history", "V7", "--quantity", "ch1.amplitude", "--db", db, "--json")).out)
    (point,) = hist["records"]
    assert point["value"] == doc["channels"]["ch1"]["amplitude"]
    assert point["uncertainty"] == doc["channels"]["ch1"]["u_amplitude"]
    assert point["date"] == "2024-05-01T10:00:00+02:00" and point["job"] == "fit"
    from senscal.registry import open_registry, sha256_file

    with open_registry(db) as reg:
        (cal,) = reg.calibrations("V7")
    assert cal.result == doc and cal.input_files[0]["sha256"] == sha256_file(path)
    assert {q.name for q in cal.quantities} >= {"ch1.phase", "ch2.frequency", "ch2.offset"}
    assert path.read_bytes() == before  # input never modified


def test_simulated_history_import_due_plot(cli, tmp_path):
    _ok(cli("simulate", "registry", "--out", tmp_path, "--seed", "5", "--drift", "0.002"))
    truth = json.loads((tmp_path / "history_truth.json").read_text())
    db = f"sqlite:///{tmp_path / 'sim.sqlite'}"
    _ok(cli("registry", "import", tmp_path / "history.json", "--db", db))
    png = tmp_path / "due.png"
    due = json.loads(_ok(cli("registry", "due", "SIM-001", "--quantity", "sensitivity", "--tolerance", "1%",
                             "--plot", png, "--json", "--db", db)).out)
    assert abs(due["drift_per_year"] - truth["drift_per_year"]) < 4 * due["u_drift_per_year"]
    assert due["significant"] and png.stat().st_size > 10_000


def test_db_file_that_does_not_exist_needs_create(cli, tmp_path):
    """A typo in --db must not open (and leave behind) an empty registry."""
    typo = tmp_path / "lab.sqllite"
    for args in (["sensors"], ["history", "A1"], ["due", "A1", "--quantity", "s", "--tolerance", "1%"], ["verify"],
                 ["export", str(tmp_path / "x.json")],
                 ["record", "A1", "--quantity", "s", "--value", "1", "--uncertainty", "0.1", "--k", "2", "--unit", "V",
                  "--date", "2024-01-01"]):
        _one_line_error(cli("registry", *args, "--db", typo), f"registry file {typo} does not exist", "--create")
        _one_line_error(cli("registry", *args, "--db", f"sqlite:///{typo}"), "does not exist")
        assert not typo.exists()
    assert not (tmp_path / "x.json").exists()
    # --create makes it on purpose; add, import and record --create-sensor create it without being asked.
    r = _ok(cli("registry", "sensors", "--db", typo, "--create", "--json"))
    assert json.loads(r.out)["sensors"] == [] and typo.exists()
    _ok(cli("registry", "add", "A1", "--kind", "accelerometer", "--db", tmp_path / "added.sqlite"))
    _ok(cli("registry", "record", "B2", "--quantity", "s", "--value", "1", "--uncertainty", "0.1", "--k", "2", "--unit", "V",
            "--date", "2024-01-01", "--create-sensor", "accelerometer", "--db", tmp_path / "recorded.sqlite"))
    exported = tmp_path / "e.json"
    _ok(cli("registry", "export", exported, "--db", tmp_path / "added.sqlite"))
    _ok(cli("registry", "import", exported, "--db", tmp_path / "imported.sqlite"))
    for name in ("added", "recorded", "imported"):
        assert (tmp_path / f"{name}.sqlite").exists()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the default folder checked is the Linux one")
def test_default_registry_is_created_on_first_use(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("SENSCAL_DB", str(tmp_path / "env" / "registry.sqlite"))
    r = _ok(cli("registry", "sensors", "--json"))
    assert json.loads(r.out)["sensors"] == [] and (tmp_path / "env" / "registry.sqlite").exists()
    monkeypatch.delenv("SENSCAL_DB")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    _ok(cli("registry", "sensors"))
    assert (tmp_path / "xdg" / "senscal" / "registry.sqlite").exists()


def test_drift_compares_units_as_units(cli, tmp_path):
    db = tmp_path / "r.sqlite"
    for year, value, unit in ((2020, 0.01000, "V/(m/s^2)"), (2021, 0.01004, "V/(m/s²)"), (2022, 0.01008, "V s^2/m")):
        _ok(cli("registry", "record", "A1", "--quantity", "s", "--value", value, "--uncertainty", "2e-6", "--k", "2",
                "--unit", unit, "--date", f"{year}-03-01", "--create-sensor", "accelerometer", "--db", db))
    due = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "s", "--tolerance", "2%", "--json",
                             "--db", db)).out)
    assert due["n_records"] == 3 and due["unit"] == "V/(m/s^2)"
    assert due["drift_per_year"] == pytest.approx(4e-5, rel=5e-3)
    # Another scale is converted into the first record's unit: 10.12 mV/(m/s^2) continues the line exactly.
    _ok(cli("registry", "record", "A1", "--quantity", "s", "--value", "10.12", "--uncertainty", "0.002", "--k", "2",
            "--unit", "mV/(m/s^2)", "--date", "2023-03-01", "--db", db))
    due = json.loads(_ok(cli("registry", "due", "A1", "--quantity", "s", "--tolerance", "2%", "--json",
                             "--db", db)).out)
    assert due["n_records"] == 4 and due["unit"] == "V/(m/s^2)"
    assert due["drift_per_year"] == pytest.approx(4e-5, rel=5e-3)
    # Another dimension is no drift of this quantity: refused with one line.
    _ok(cli("registry", "record", "A1", "--quantity", "s", "--value", "0.1", "--uncertainty", "0.002", "--k", "2",
            "--unit", "V/(m/s)", "--date", "2024-03-01", "--db", db))
    _one_line_error(cli("registry", "due", "A1", "--quantity", "s", "--tolerance", "2%", "--db", db),
                    "cannot be converted", "V/(m/s)")


def test_record_needs_k_and_a_unit(cli, tmp_path):
    """Issue 31: --k has no default (certificates quote k=2 or k=1); --unit must be a unit."""
    db = tmp_path / "r.sqlite"
    base = ["registry", "record", "A1", "--quantity", "s", "--value", "0.01", "--uncertainty", "2e-5",
            "--date", "2024-03-01", "--create-sensor", "accelerometer", "--db", db]
    _one_line_error(cli(*base, "--unit", "V/(m/s^2)"), "give --k", "--k 2")
    _one_line_error(cli(*base, "--unit", "volts-ish", "--k", "2"), "--unit", "not a unit")
    _one_line_error(cli("registry", "add", "B9", "--kind", "accelerometer", "--nominal", "sensitivity=0.01 V/blorb",
                        "--db", db), "--nominal sensitivity", "not a unit")
    r = json.loads(_ok(cli(*base, "--unit", "V/(m/s^2)", "--k", "2", "--json")).out)
    assert r["quantities"][0]["uncertainty"] == pytest.approx(1e-5)
