"""``senscal gfimu`` and ``senscal simulate gfimu`` end to end, and their one-line errors."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pandas as pd
import pytest


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    """A short simulated recording written through the Python API (the CLI is tested below)."""
    from senscal.gfimu import paper_layout, write_layout
    from senscal.io import write_recording
    from senscal.simulate.gfimu import simulate_gfimu

    d = tmp_path_factory.mktemp("gfimu")
    rec, truth, _ = simulate_gfimu(fs=500, duration=2, seed=3)
    write_recording(rec, d / "gfimu.csv")
    write_recording(truth, d / "gfimu_truth.csv")
    write_layout(paper_layout(), d / "layout.csv")
    return d


def test_simulate_writes_files(cli, tmp_path):
    r = cli("simulate", "gfimu", "--out", tmp_path, "--fs", "500", "--duration", "2", "--seed", "3")
    assert r.code == 0, r.err
    rec = pd.read_csv(tmp_path / "gfimu.csv")
    assert list(rec.columns) == ["t"] + [f"a{k}{ax}" for k in range(1, 5) for ax in "xyz"]
    assert len(rec) == 1000
    truth = pd.read_csv(tmp_path / "gfimu_truth.csv")
    assert {"t", "wx", "wy", "wz", "qw"} <= set(truth.columns)
    info = json.loads((tmp_path / "gfimu_truth.json").read_text())
    assert info["fs_hz"] == 500 and len(info["bias_m_s2"]) == 12
    assert (tmp_path / "layout.csv").read_text().startswith("name,x,y,z,nx,ny,nz")
    assert cli("simulate", "gfimu", "--out", tmp_path, "--fs", "-5").code == 2


def test_gfimu_all_with_truth_attitude_out_plot(cli, sim, tmp_path):
    f = sim / "gfimu.csv"
    before = hashlib.sha256(f.read_bytes()).hexdigest()
    out, png = tmp_path / "w.csv", tmp_path / "w.png"
    r = cli("gfimu", f, "--method", "all", "--truth", sim / "gfimu_truth.csv", "--attitude",
            "--out", out, "--plot", png, "--lag", "5", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["methods"] == ["integration", "sqrt", "differential", "kalman"]
    for m in doc["methods"]:
        for ax in ("wx", "wy", "wz"):
            e = doc["errors"][m][ax]
            assert e["max_abs_error"] >= e["std_error"] >= 0
    assert doc["errors"]["kalman"]["wz"]["std_error"] < doc["errors"]["sqrt"]["wz"]["std_error"]
    assert doc["attitude"]["max_error_deg"] >= doc["attitude"]["final_error_deg"] >= 0
    df = pd.read_csv(out)
    want = ["t"] + [f"{m}_{ax}" for m in doc["methods"] for ax in ("wx", "wy", "wz")] + \
        ["alpha_x", "alpha_y", "alpha_z", "f_x", "f_y", "f_z", "qw", "qx", "qy", "qz"]
    assert list(df.columns) == want
    np.testing.assert_allclose(np.linalg.norm(df[["qw", "qx", "qy", "qz"]].to_numpy(), axis=1), 1.0, atol=1e-12)
    assert png.stat().st_size > 10_000
    assert hashlib.sha256(f.read_bytes()).hexdigest() == before


def test_gfimu_single_method_columns_and_human_output(cli, sim, tmp_path):
    out = tmp_path / "k.csv"
    r = cli("gfimu", sim / "gfimu.csv", "--out", out, "--initial-omega", "0,0,0")
    assert r.code == 0, r.err
    assert "condition number" in r.out and "k=2" in r.out
    assert list(pd.read_csv(out).columns)[:4] == ["t", "wx", "wy", "wz"]


def test_gfimu_custom_layout_equals_default(cli, sim):
    a = json.loads(cli("gfimu", sim / "gfimu.csv", "--method", "integration", "--truth", sim / "gfimu_truth.csv",
                       "--json").out)
    b = json.loads(cli("gfimu", sim / "gfimu.csv", "--method", "integration", "--layout", sim / "layout.csv",
                       "--truth", sim / "gfimu_truth.csv", "--json").out)
    assert a["errors"] == b["errors"]


@pytest.mark.parametrize("args, msg", [
    (["--method", "gyro"], "--method"),
    (["--observation", "magic"], "--observation"),
    (["--initial-omega", "1,2"], "three numbers"),
    (["--initial-omega", "a,b,c"], "not a number"),
    (["--distance", "0.04", "--layout", "LAYOUT"], "not both"),
    (["--distance", "-1"], "positive"),
    (["--lag", "0"], "lag"),
    (["--layout", "COPLANAR"], "coplanar"),
    (["--truth", "MISSING.csv"], "not found"),
    (["--bias-std", "-1e-3"], "--bias-std"),
    (["--bias-std", "1e-3", "--observation", "sqrt"], "quadratic"),
])
def test_gfimu_user_errors_are_one_line(cli, sim, tmp_path, args, msg):
    cop = tmp_path / "cop.csv"
    rows = ["name,x,y,z,nx,ny,nz"] + [f"a{k}{ax},{k * 0.01},{(k % 2) * 0.02},0,{ax == 'x':d},{ax == 'y':d},{ax == 'z':d}"
                                      for k in range(1, 5) for ax in "xyz"]
    cop.write_text("\n".join(rows) + "\n")
    args = [str(cop) if a == "COPLANAR" else str(sim / "layout.csv") if a == "LAYOUT" else a for a in args]
    r = cli("gfimu", sim / "gfimu.csv", *args)
    assert r.code == 2
    assert msg in r.err and "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1


def test_gfimu_missing_channel(cli, tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("t,a1x\n0,1\n0.1,2\n")
    r = cli("gfimu", p)
    assert r.code == 2 and "a1y" in r.err


def test_gfimu_bias_std_reports_offsets(cli, sim):
    from senscal.gfimu import UNKNOWNS, paper_layout, solve_kinematics
    from senscal.io import read_recording

    r = cli("gfimu", sim / "gfimu.csv", "--bias-std", "9.80665e-4", "--json")
    assert r.code == 0, r.err
    f = json.loads(r.out)["filter"]
    assert f["bias_std_m_s2"] == pytest.approx(9.80665e-4)
    assert list(f["offsets"]) == list(UNKNOWNS[3:])
    assert all(o["u"] > 0 for o in f["offsets"].values())
    # The offsets are the biases' image through the solve: compare with the simulator's biases.
    from senscal.simulate.gfimu import simulate_gfimu

    _, _, inf = simulate_gfimu(fs=500, duration=2, seed=3)
    kin = solve_kinematics(read_recording(sim / "gfimu.csv").data(list(paper_layout().names)), paper_layout())
    b = np.array([inf["bias_m_s2"][n] for n in paper_layout().names])
    true = (kin.sensitivity @ b)[3:12]
    for name, tv in zip(UNKNOWNS[3:], true):
        assert abs(f["offsets"][name]["value"] - tv) < 4 * f["offsets"][name]["u"]
    human = cli("gfimu", sim / "gfimu.csv", "--bias-std", "9.80665e-4")
    assert human.code == 0 and "Constant errors" in human.out


def test_gfimu_smooth_option(cli, sim):
    args = ("gfimu", sim / "gfimu.csv", "--truth", sim / "gfimu_truth.csv", "--json")
    f = json.loads(cli(*args).out)
    s = json.loads(cli(*args, "--smooth").out)
    assert f["filter"]["smoothed"] is False and s["filter"]["smoothed"] is True
    # Every sample then uses the whole record: the stated uncertainty can only shrink.
    for ax in ("wx", "wy", "wz"):
        assert s["filter"]["median_u_omega"][ax] <= f["filter"]["median_u_omega"][ax]
    human = cli("gfimu", sim / "gfimu.csv", "--smooth")
    assert human.code == 0 and "smoother" in human.out
