"""The gfimu job (``senscal.jobs.gfimu``): the Python API and ``senscal gfimu --json`` agree."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from senscal import jobs
from senscal.errors import InputError
from senscal.io import read_recording
from senscal.jobs.gfimu import GfimuOptions, GfimuResult, gfimu


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.gfimu import paper_layout, write_layout
    from senscal.io import write_recording
    from senscal.simulate.gfimu import simulate_gfimu

    out = tmp_path_factory.mktemp("gfimujobs")
    rec, truth, _ = simulate_gfimu(fs=500.0, duration=3.0, seed=11, rest_s=0.5)
    write_recording(rec, out / "gfimu.csv")
    write_recording(truth, out / "gfimu_truth.csv")
    write_layout(paper_layout(0.04), out / "layout.csv")
    return out


def _same_document(a, b):
    """Document ``a`` equals ``b`` exactly: same keys in the same order, every number equal."""
    assert list(a) == list(b)
    assert a == b


@pytest.mark.parametrize("words, opts", [
    (["--method", "all", "--attitude"], dict(method="all", attitude=True)),
    (["--rest", "0:0.5", "--initial-omega", "0,0,0"], dict(rest=(0.0, 0.5))),
    (["--plain", "--smooth", "--noise-std", "0.01"], dict(plain=True, smooth=True, noise_std=0.01)),
])
def test_api_equals_cli_json(cli, sim, tmp_path, words, opts):
    out = tmp_path / "w.csv"
    r = cli("gfimu", sim / "gfimu.csv", "--truth", sim / "gfimu_truth.csv", "--out", out, "--json", *words)
    assert r.code == 0, r.err
    cli_doc = json.loads(r.out)
    assert cli_doc.pop("out") == str(out)
    res = gfimu(sim / "gfimu.csv", GfimuOptions(truth=sim / "gfimu_truth.csv", **opts))
    assert isinstance(res, GfimuResult)
    _same_document(res.to_dict(), cli_doc)
    assert list(res.warnings) == cli_doc["warnings"]
    # --out writes the job's arrays (and the data frame is the same table).
    # (pandas, not read_recording: senscal's CSV reader takes a first data row with empty NaN fields for a
    # second header row.)
    written = pd.read_csv(out)
    df = res.to_dataframe()
    assert list(df.columns) == list(written.columns)
    for name in written.columns:
        np.testing.assert_allclose(written[name], df[name], rtol=1e-12, equal_nan=True)


def test_options_builder_parses_the_command_words(sim):
    from senscal.cli.cmd_gfimu import JOB_OPTIONS

    build = JOB_OPTIONS["gfimu"]
    assert build(rest="0:2", initial_omega="1,2,3", out=None, plot=None, json_out=True) == \
        GfimuOptions(rest=(0.0, 2.0), initial_omega=(1.0, 2.0, 3.0))
    assert build(layout_file=sim / "layout.csv", method="all") == GfimuOptions(layout=sim / "layout.csv", method="all")
    with pytest.raises(InputError, match="--initial-omega needs three numbers"):
        build(initial_omega="1,2")
    with pytest.raises(InputError, match="--rest needs START:END"):
        build(rest="2")


def test_layout_file_in_memory_and_default_agree(sim):
    from senscal.gfimu import paper_layout

    a = jobs.run("gfimu", sim / "gfimu.csv", jobs.options("gfimu", layout=sim / "layout.csv"))
    b = gfimu(read_recording(sim / "gfimu.csv"), GfimuOptions(layout=paper_layout(0.04)))
    np.testing.assert_array_equal(a.omega["kalman"], b.omega["kalman"])
    assert a.to_dict()["layout"]["source"] == str(sim / "layout.csv")
    assert b.to_dict()["layout"]["source"] == "<layout>"
    assert gfimu(sim / "gfimu.csv").to_dict()["layout"]["source"] == "paper, L = 0.04 m"


@pytest.mark.parametrize("opts, msg", [
    (dict(lag=0), "--lag must be at least 1"),
    (dict(noise_std=-1.0), "--noise-std must be a positive"),
    (dict(bias_std=0.1, rest=(0.0, 0.5)), "give one of them"),
    (dict(plain=True, bias_std=0.1), "--plain is the filter without"),
    (dict(observation="sqrt", rest=(0.0, 0.5)), "need --observation quadratic"),
    (dict(layout="l.csv", distance=0.05), "either --layout or --distance"),
    (dict(method="gyro"), "--method must be one of"),
    (dict(observation="cubic"), "--observation must be one of"),
    (dict(differential_max_u=0.0), "--differential-max-u must be a positive"),
    (dict(initial_omega=(1.0, 2.0)), "three numbers"),
])
def test_contradicting_options_are_refused_before_reading(opts, msg, tmp_path):
    # The recording does not exist: the options are checked first.
    with pytest.raises(InputError, match=msg):
        gfimu(tmp_path / "missing.csv", GfimuOptions(**opts))


def test_no_registry_quantities_and_truth_must_cover(sim, tmp_path):
    assert gfimu(sim / "gfimu.csv").quantities() == ()
    short = read_recording(sim / "gfimu_truth.csv")
    from senscal.io import Recording, write_recording

    half = Recording(channels={k: v[: v.size // 2] for k, v in short.channels.items()}, t=short.time[: short.time.size // 2])
    write_recording(half, tmp_path / "half.csv")
    with pytest.raises(InputError, match="give a truth that covers the recording"):
        gfimu(sim / "gfimu.csv", GfimuOptions(truth=tmp_path / "half.csv"))
