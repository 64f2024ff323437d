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
