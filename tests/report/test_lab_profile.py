"""Lab profile, run file and --env parsing; which source wins."""

from __future__ import annotations

import pytest

from senscal.cli.cert_opts import cert_fields, certificate_info
from senscal.errors import InputError
from senscal.report.lab import Condition, load_run_file, missing_fields, parse_condition

PROFILE = """
name = "Lab"
address = "Street 1"
approvers = ["A. Person"]
standards = [{name = "Ref", certificate = "C-1", u_relative = 0.001}]

[run]
location = "hall 1"
customer = "from profile"
item = "from profile"
"""


@pytest.mark.parametrize("text, expected", [
    ("temperature=23.1+-0.5 degC", Condition("temperature", 23.1, 0.5, "degC")),
    ("temperature = 23.1 +/- 0.5 degC", Condition("temperature", 23.1, 0.5, "degC")),
    ("pressure=1.013e5±50 Pa", Condition("pressure", 101300.0, 50.0, "Pa")),
    ("humidity=41 %RH", Condition("humidity", 41.0, None, "%RH")),
    ("offset=-0.5", Condition("offset", -0.5, None, "")),
])
def test_parse_condition(text, expected):
    assert parse_condition(text) == expected


@pytest.mark.parametrize("text", ["temperature", "=23", "t=warm", "t=23+-x degC", "t=23+--1 C", "t=1e999", "t=nan"])
def test_parse_condition_refuses(text):
    with pytest.raises(InputError, match="NAME=VALUE|non-negative"):
        parse_condition(text)


def test_run_file_table_or_top_level(tmp_path):
    (tmp_path / "a.toml").write_text('[run]\ncustomer = "X"\nconditions = {temperature = {value = 23, u = 0.5, unit = "degC"}}\n')
    (tmp_path / "b.yaml").write_text("customer: X\nconditions:\n  - {name: temperature, value: 23, u: 0.5, unit: degC}\n")
    a, b = load_run_file(tmp_path / "a.toml"), load_run_file(tmp_path / "b.yaml")
    assert a == b and a.conditions == (Condition("temperature", 23.0, 0.5, "degC"),)
    (tmp_path / "c.json").write_text("{}")
    with pytest.raises(InputError, match="use a .toml or .yaml file"):
        load_run_file(tmp_path / "c.json")


def test_options_win_over_run_file_over_profile(tmp_path, monkeypatch):
    (tmp_path / "lab.toml").write_text(PROFILE)
    (tmp_path / "run.toml").write_text('customer = "from run file"\nserial = "S-1"\n')
    params = dict(lab=tmp_path / "lab.toml", run_file=tmp_path / "run.toml", customer=None, item="from option",
                  sensor_id=None, sensor="REG-1", env=["temperature=23+-0.5 degC"], date="2026-01-05T10:00:00")
    fields = {k: v for k, v in cert_fields(params).items() if k not in ("sign_key", "sign_cert")}  # signing: elsewhere
    info = certificate_info(**fields)
    run = info.run
    assert (run.customer, run.item, run.location) == ("from run file", "from option", "hall 1")
    assert run.serial == "REG-1"                        # the registry's --sensor when no --serial
    assert run.calibration_date == "2026-01-05"         # the registry's --date, its date part
    assert missing_fields(info) == []
    # $SENSCAL_LAB is the default profile
    monkeypatch.setenv("SENSCAL_LAB", str(tmp_path / "lab.toml"))
    assert certificate_info().lab.name == "Lab"
    assert certificate_info().run.customer == "from profile"
