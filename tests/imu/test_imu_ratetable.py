"""senscal imu calibrate --rate-table and the IMU certificate (--report, --dcc) (issue 27).

Coverage of the rate-table cases runs in test_imu.py::test_coverage (senscal.validation.imu.SCENARIOS holds
them: 2 seeds each in CI, 200 with SENSCAL_MC=full in benchmarks/bench_coverage.py imu --only rate-table).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from senscal.errors import InputError

SHARED_SCHEMAS = Path(__file__).resolve().parents[3] / "shared" / "schemas" / "dcc"

LAB = """name = "Inertial Lab"
address = "Bundesallee 100, Braunschweig"
country = "DE"
email = "lab@example.org"
approvers = [{name = "A. Approver", role = "Head of laboratory"}]
[[standards]]
name = "Rate table RT-1"
serial = "RT-1"
certificate = "DKD-K-1234"
traceability = "PTB"
due = "2027-06-30"
[run]
customer = "ACME Robotics"
customer_address = "1 Main St, Springfield"
customer_email = "qa@acme.example"
item = "MEMS IMU"
manufacturer = "ACME"
location = "laboratory"
"""


@pytest.fixture(scope="module")
def table_session():
    from senscal.simulate.imu import simulate_imu
    from senscal.simulate.imu_table import TableSpec

    return simulate_imu(seed=5, n_poses=20, rate_table=TableSpec(hold_s=10.0))


@pytest.fixture(scope="module")
def job(table_session):
    from senscal.jobs.imu import ImuOptions, imu_calibrate
    from senscal.simulate.imu_table import rate_table_of

    rec, tr = table_session
    return imu_calibrate(rec, ImuOptions(rate_table=rate_table_of(tr)))


class _Run:
    def __init__(self, code, out, err):
        self.exit_code, self.stdout, self.err = code, out, err


def _cli(capsys, *args):
    from senscal.cli import main

    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code or 0
    cap = capsys.readouterr()
    return _Run(code, cap.out, cap.err)


def test_reader_csv_and_yaml_agree(tmp_path):
    from senscal.io.ratetable import rate_table_text, read_rate_table

    c = tmp_path / "t.csv"
    c.write_text("# a table\nstart, stop, axis, rate, u_rate, u_axis\n"
                 "10 s, 20 s, +z, 30 deg/s, 0.01 %, 0.05 deg\n"
                 "21000 ms, 0.5 min, 0 0.6 -0.8, -0.5 rad/s, 1e-4 rad/s, 1 mrad\n")
    y = tmp_path / "t.yaml"
    y.write_text("segments:\n  - {start: 10 s, stop: 20 s, axis: z, rate: 30 deg/s, u_rate: 0.01 %, u_axis: 0.05 deg}\n"
                 "  - {start: 21 s, stop: 30 s, axis: [0, 0.6, -0.8], rate: -0.5 rad/s, u_rate: 1e-4 rad/s, "
                 "u_axis: 1 mrad}\n")
    a, b = read_rate_table(c), read_rate_table(y)
    for k in ("start", "stop", "axis", "rate", "u_rate", "u_axis"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-12)
    assert a.rate[0] == pytest.approx(math.radians(30)) and a.u_rate[0] == pytest.approx(1e-4 * math.radians(30))
    np.testing.assert_allclose(a.axis[1], [0, 0.6, -0.8])
    assert a.u_axis[1] == pytest.approx(1e-3) and a.stop[1] == pytest.approx(30.0)
    # The writer's text reads back.
    back = tmp_path / "w.csv"
    back.write_text(rate_table_text(a))
    np.testing.assert_allclose(read_rate_table(back).rate, a.rate, rtol=1e-10)


@pytest.mark.parametrize("row, match", [
    ("10 s, 20 s, z, 30, 0.01 deg/s", "rate '30' has no unit"),
    ("10, 20 s, z, 30 deg/s, 0.01 deg/s", "start '10' has no unit"),
    ("10 s, 20 s, z, 30 m/s, 0.01 deg/s", "cannot be converted"),
    ("10 s, 5 s, z, 30 deg/s, 0.01 deg/s", "not after start"),
    ("10 s, 20 s, w, 30 deg/s, 0.01 deg/s", "not an axis"),
])
def test_reader_refuses_with_the_fix(tmp_path, row, match):
    from senscal.io.ratetable import read_rate_table

    p = tmp_path / "t.csv"
    p.write_text("start, stop, axis, rate, u_rate\n" + row + "\n")
    with pytest.raises(InputError, match=match):
        read_rate_table(p)


def test_table_sharpens_the_gyro_and_covers(job, table_session):
    """The table's segments shrink the gyro scale u below the poses' alone and the estimate still covers."""
    _, tr = table_session
    r = job.result
    g, tg, fit = r.gyroscope, tr["gyroscope"], r.rate_table
    u_pose = np.sqrt(np.diag(fit.pose_covariance))[[0, 4, 8]]
    assert np.all(g.u_scale < 0.8 * u_pose)
    for i, a in enumerate("xyz"):
        assert abs(g.scale[i] - tg[f"scale_{a}"]) < 4 * g.u_scale[i]
    # The budget's components add up to the combined covariance (they split it exactly).
    np.testing.assert_allclose(sum(c for _, _, c in fit.components), fit.covariance, rtol=1e-8, atol=1e-30)
    assert fit.dof == 18 and fit.chi2 < 42.3  # chi2(18) 99.9 % point
    assert not any(w.startswith("rate-table-inconsistent") for w in r.warnings)
    doc = job.to_dict()
    assert doc["rate_table"]["n_segments"] == 6 and doc["rate_table"]["table_only"] is not None
    assert [c["type"] for c in doc["budget"]["gyroscope"]] == ["A", "A", "A", "B", "B"]


def test_wrong_table_rate_is_named(table_session):
    from dataclasses import replace

    from senscal.imu import calibrate_imu
    from senscal.simulate.imu_table import rate_table_of

    rec, tr = table_session
    tab = rate_table_of(tr)
    wrong = replace(tab, rate=tab.rate * (1 + 1e-3))  # 20 times the stated u
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                      rate_table=wrong)
    assert any(w.startswith("rate-table-inconsistent") for w in r.warnings)
    assert r.rate_table.inflation > 1


def test_cli_bad_table_one_line_exit_2(tmp_path, capsys, table_session):
    from senscal.io import write_recording
    from senscal.io.ratetable import rate_table_text
    from senscal.simulate.imu_table import rate_table_of

    rec, tr = table_session
    p = write_recording(rec, tmp_path / "imu.csv", units_in_header=True)
    tab = rate_table_of(tr)
    span = float(rec.time[-1] - rec.time[0])
    cases = {
        "outside": ("start, stop, axis, rate, u_rate\n"
                    f"{span - 5:.3f} s, {span + 10:.3f} s, z, 57.3 deg/s, 0.003 deg/s\n", "outside"),
        "units": ("start, stop, axis, rate, u_rate\n10 s, 20 s, z, 57.3, 0.003 deg/s\n", "has no unit"),
    }
    for name, (text, match) in cases.items():
        f = tmp_path / f"{name}.csv"
        f.write_text(text)
        res = _cli(capsys, "imu", "calibrate", p, "--rate-table", f)
        assert res.exit_code == 2, (name, res.err)
        assert match in res.err and "Traceback" not in res.err and len(res.err.strip().splitlines()) == 1
    # A gyro clipped at +-0.8 rad/s: the table's 1 rad/s is beyond its range.
    from senscal.imu import calibrate_imu

    gyr = np.clip(rec.data(["gx", "gy", "gz"]), -0.8, 0.8)
    with pytest.raises(InputError, match="beyond the gyro's range"):
        calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), gyr, gyro_unit="rad/s", rate_table=tab)
    good = tmp_path / "table.csv"
    good.write_text(rate_table_text(tab))
    assert good.read_text().count("\n") == 2 + tab.n_segments


def test_certificate_html_pdf_and_dcc(job, tmp_path):
    """The IMU certificate renders (HTML, PDF) with both triads and the gyro budget; the DCC validates."""
    from senscal.report.certificate import certificate_bytes
    from senscal.report.dcc import DCC_NS, dcc_xml, read_dcc_quantities
    from dataclasses import replace

    from senscal.report.lab import CertificateInfo, Condition, load_lab_profile

    lab_file = tmp_path / "lab.toml"
    lab_file.write_text(LAB)
    lab, run = load_lab_profile(lab_file)
    info = CertificateInfo(lab, replace(run, serial="IMU-7", calibration_date="2026-11-27",
                                        certificate_id="IMU-2026-0001",
                                        conditions=(Condition("temperature", 23.0, 0.5, "degC"),)))
    html = certificate_bytes(".html", "imu", job, info=info, method="multi-pose", files=["imu.csv"]).decode()
    assert "IMU accelerometer and gyroscope" in html and "gyro_scale_x" in html and "accel_alpha" in html
    assert "table rate, stated u (type B)" in html and "gyro misalignment" in html and "<svg" in html
    pdf = certificate_bytes(".pdf", "imu", job, info=info, method="multi-pose", files=["imu.csv"])
    assert pdf.startswith(b"%PDF") and len(pdf) > 20_000
    xml = dcc_xml("imu-calibrate", job, info, files=["imu.csv"])  # validated against the vendored schema
    q = read_dcc_quantities(xml)
    g = job.result.gyroscope
    assert q["senscal_gyroscope_scale_x"]["value"][0] == pytest.approx(g.scale[0], rel=1e-11)
    assert q["senscal_gyroscope_scale_x"]["U"][0] == pytest.approx(2 * g.u_scale[0], rel=1e-11)
    assert "senscal_accelerometer_Kx" in q and "senscal_gyroscope_misalignment_zy@\\degree" in q
    assert DCC_NS.encode() in xml
    if (SHARED_SCHEMAS / "dcc.xsd").is_file():
        import xmlschema

        d = SHARED_SCHEMAS
        si = d / "SI_Format.xsd" if (d / "SI_Format.xsd").is_file() else d.parent / "SI_Format.xsd"
        schema = xmlschema.XMLSchema(str(d / "dcc.xsd"), locations={"https://ptb.de/si": str(si)}, allow="local")
        schema.validate(xml.decode())


@pytest.mark.skipif(not (SHARED_SCHEMAS / "dcc.xsd").is_file(), reason="../shared/schemas/dcc not present")
def test_cli_report_and_dcc(tmp_path, capsys, table_session):
    """`imu calibrate --rate-table --report --dcc` as a user runs it; the DCC is valid against the shared schema."""
    import xmlschema

    from senscal.io import write_recording
    from senscal.io.ratetable import rate_table_text
    from senscal.simulate.imu_table import rate_table_of

    rec, tr = table_session
    p = write_recording(rec, tmp_path / "imu.csv", units_in_header=True)
    t = tmp_path / "table.csv"
    t.write_text(rate_table_text(rate_table_of(tr)))
    lab = tmp_path / "lab.toml"
    lab.write_text(LAB)
    res = _cli(capsys, "imu", "calibrate", p, "--rate-table", t, "--lab", lab, "--serial", "IMU-7",
               "--calibration-date", "2026-11-27", "--env", "temperature=23.0+-0.5 degC",
               "--report", tmp_path / "c.html", "--dcc", tmp_path / "c.xml", "--json")
    assert res.exit_code == 0, res.err
    doc = json.loads(res.stdout)
    assert doc["report"].endswith("c.html") and doc["rate_table"]["consistency"]["dof"] == 18
    assert "budget-zero-component" in res.err and "u_axis in --rate-table" in res.err  # u_axis stated as 0
    d = SHARED_SCHEMAS
    si = d / "SI_Format.xsd" if (d / "SI_Format.xsd").is_file() else d.parent / "SI_Format.xsd"
    schema = xmlschema.XMLSchema(str(d / "dcc.xsd"), locations={"https://ptb.de/si": str(si)}, allow="local")
    schema.validate((tmp_path / "c.xml").read_text())
    assert "MEMS IMU" in (tmp_path / "c.html").read_text()


def test_cli_inconsistent_table_strict_exit_3(tmp_path, capsys, table_session):
    """A table stating its rate 0.1 % high (20 u): rate-table-inconsistent on stderr, --strict exits 3."""
    from dataclasses import replace

    from senscal.io import write_recording
    from senscal.io.ratetable import rate_table_text
    from senscal.simulate.imu_table import rate_table_of

    rec, tr = table_session
    p = write_recording(rec, tmp_path / "imu.csv", units_in_header=True)
    tab = rate_table_of(tr)
    t = tmp_path / "wrong.csv"
    t.write_text(rate_table_text(replace(tab, rate=tab.rate * (1 + 1e-3))))
    res = _cli(capsys, "imu", "calibrate", p, "--rate-table", t, "--json", "--strict")
    assert res.exit_code == 3 and "rate-table-inconsistent" in res.err and "Traceback" not in res.err
    doc = json.loads(res.stdout)
    assert doc["rate_table"]["consistency"]["inflation"] > 1
