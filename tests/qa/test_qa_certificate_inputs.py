"""QA: lab profiles, run files and certificate options that are malformed or hostile.

Each case was an internal error (exit 1) or a certificate that stated a
wrong thing without a word (a string of approvers read letter by letter, a
negative uncertainty printed as given); now one line on stderr (exit 2),
nothing written.
"""

from __future__ import annotations

import pytest

from senscal.errors import InputError
from senscal.report.lab import load_lab_profile, load_run_file

LAB = """name = "Vibration Laboratory Nord"
address = "Hafenstrasse 7, 20457 Hamburg, Germany"
approvers = [{name = "Dr. Ada Pruefer", role = "Head of laboratory"}]

[[standards]]
name = "Reference accelerometer"
due = "2027-03-01"
u_relative = 0.0005
"""


@pytest.fixture(autouse=True)
def no_user_profile(monkeypatch, tmp_path):
    monkeypatch.delenv("SENSCAL_LAB", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))


def _lab(tmp_path, text: str, name: str = "lab.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_valid_profile_reads(tmp_path):
    lab, _ = load_lab_profile(_lab(tmp_path, LAB))
    assert [a.name for a in lab.approvers] == ["Dr. Ada Pruefer"]
    assert lab.standards[0].u_relative == 0.0005


@pytest.mark.parametrize("old, new, match", [
    # A string was iterated letter by letter: seven approvers 'D', 'r', '.', ...
    ('approvers = [{name = "Dr. Ada Pruefer", role = "Head of laboratory"}]', 'approvers = "Dr. Ada"', "must be a list"),
    # Was TypeError (exit 1).
    ('approvers = [{name = "Dr. Ada Pruefer", role = "Head of laboratory"}]', "approvers = 5", "must be a list"),
    # Printed on the certificate as given; the u-below-reference check compared against it.
    ("u_relative = 0.0005", "u_relative = -0.5", "finite number >= 0"),
    ("u_relative = 0.0005", "u_relative = inf", "finite number >= 0"),
    # Printed as the standard's due date.
    ('due = "2027-03-01"', 'due = "tomorrow"', "not a calendar date"),
])
def test_bad_lab_profile(tmp_path, old, new, match):
    with pytest.raises(InputError, match=match) as exc:
        load_lab_profile(_lab(tmp_path, LAB.replace(old, new)))
    assert "\n" not in str(exc.value)


def test_toml_date_for_due_is_read(tmp_path):
    lab, _ = load_lab_profile(_lab(tmp_path, LAB.replace('due = "2027-03-01"', "due = 2027-03-01")))
    assert lab.standards[0].due == "2027-03-01"


@pytest.mark.parametrize("cond", ['{name = "temperature", value = 23, u = -1, unit = "degC"}',
                                  '{name = "temperature", value = nan, u = 1, unit = "degC"}',
                                  '{name = "temperature", value = 23, u = inf, unit = "degC"}'])
def test_bad_condition_in_run_file(tmp_path, cond):
    # --env refused these; the run file's conditions printed them on the certificate.
    with pytest.raises(InputError, match="finite value"):
        load_run_file(_lab(tmp_path, f"[run]\nconditions = [{cond}]\n", "run.toml"))


def test_cli_bad_profile_writes_nothing(cli, tmp_path):
    r = cli("simulate", "hydraulic", "--out", tmp_path / "hy", "--seed", "1", "--freqs", "2,4")
    assert r.code == 0, r.err
    hy = sorted((tmp_path / "hy").glob("hydraulic_*.csv"))
    lab = _lab(tmp_path, LAB.replace("u_relative = 0.0005", "u_relative = -0.5"))
    r = cli("velocity", *hy, "--position", "position", "--velocity", "velocity", "--lab", lab,
            "--report", tmp_path / "out" / "c.html", "--dcc", tmp_path / "out" / "c.xml", "--mkdir")
    assert r.code == 2 and "Traceback" not in r.err, r.err
    assert len([ln for ln in r.err.splitlines() if ln.strip()]) == 1 and "u_relative" in r.err, r.err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
