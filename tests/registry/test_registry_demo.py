"""The registry demo section recovers the simulated drift."""

from __future__ import annotations

from senscal.demo import job_registry


def test_demo_section(tmp_path):
    sec = job_registry.run(tmp_path, seed=3)
    drift, stable, due = sec.rows
    for row in (drift, stable):
        assert abs(row["estimate"] - row["truth"]) < 4 * row["uncertainty"]
    # The due date includes the prediction's uncertainty: not after the noiseless crossing, but after today's data.
    assert 6.0 < due["estimate"] <= due["truth"]
    assert (tmp_path / sec.plot).stat().st_size > 10_000
    assert all((tmp_path / f).exists() for f in sec.files)
