"""Fixtures shared by the certificate and DCC tests."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def no_user_profile(monkeypatch, tmp_path):
    """The user's own lab profile ($SENSCAL_LAB, ~/.config/senscal/lab.toml) must not leak into a test."""
    monkeypatch.delenv("SENSCAL_LAB", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))


@pytest.fixture(scope="module")
def centrifuge_files(tmp_path_factory) -> list[str]:
    """Two short double-centrifuge records (1 and 5 Hz, a0 = 100 m/s^2, S0 = 0.05 V/(m/s^2)) as CSV paths."""
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_centrifuge

    d = tmp_path_factory.mktemp("cf")
    recs, truth = simulate_centrifuge(frequencies=(1.0, 5.0), seed=7, min_duration=3.0)
    return [str(p) for p in write_simulation(recs, truth, d, "centrifuge")]


_LAB_HEADER = """
name = "Vibration Lab Nord"
address = "Hafenstr. 7, 20457 Hamburg"
country = "DE"
email = "lab@example.org"
{extra}approvers = [{{name = "Dr. Ada Pruefer", role = "Head of laboratory"}}]

[[standards]]
name = "Double centrifuge DC-2"
serial = "DC2-0042"
certificate = "PTB-1.21-4711"
traceability = "PTB"
due = "2099-12-31"
u_relative = {u_rel}

[run]
location = "Laboratory hall 2"
"""

_RUN_FIELDS = """customer = "ACME"
customer_email = "qa@acme.example"
customer_address = "Am Markt 1, 10115 Berlin"
manufacturer = "Qfab"
item = "servo accelerometer"
"""


def _lab_profile_text(u_rel: str = "0.0005", *, extra: str = "", run_fields: bool = True) -> str:
    """A lab profile with one traceable standard in date (DC-2); ``extra`` adds header lines, and
    ``run_fields=False`` leaves the customer and item to a run file."""
    return _LAB_HEADER.format(extra=extra, u_rel=u_rel) + (_RUN_FIELDS if run_fields else "")


@pytest.fixture(scope="session")
def lab_profile():
    """The one lab profile the certificate, conformity and signing tests share (a function: keywords as
    :func:`_lab_profile_text`)."""
    return _lab_profile_text
