"""The certificate opens in a real headless browser, offline, with its plots."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from senscal.report.certificate import write_certificate
from senscal.simulate.vibration import simulate_centrifuge
from senscal.vibration import frequency_response, response_point


@pytest.fixture(scope="module")
def certificate(tmp_path_factory):
    recs, truth = simulate_centrifuge(frequencies=(1.0, 5.0), seed=3, min_duration=5.0)
    pts = [response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"], static_sensitivity=0.05,
                          u_input=0.002, source=f"rec{i}.csv") for i, r in enumerate(recs)]
    resp = frequency_response(pts, static_sensitivity=0.05)
    path = tmp_path_factory.mktemp("cert") / "cert.html"
    write_certificate(path, "response", resp, sensor_id="SN <1&2>", model="M", unit=resp.unit,
                      conditions={"peak input acceleration (m/s^2)": 100.0}, files=["rec0.csv", "rec1.csv"])
    return path, resp


def test_certificate_content(certificate):
    path, resp = certificate
    html = path.read_text()
    assert "SN &lt;1&amp;2&gt;" in html  # user text is escaped
    assert re.search(r"Certificate id</td><td>SC-\d{8}-[0-9A-F]{8}<", html)
    # every point with its expanded uncertainty, rounded to 2 significant digits
    for p in resp.points:
        assert f"{2 * p.u_normalized_sensitivity:.2g}" in html
    assert html.count("<svg") == 1 and "phase delay" in html
    assert not re.search(r'(src|href)="(https?:)?//', html) and "<script" not in html


def test_certificate_renders_offline_in_a_browser(certificate, tmp_path):
    exe = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
    if exe is None:
        if os.environ.get("CI"):
            pytest.fail("CI must install Debian's chromium for the certificate test")
        pytest.skip("no chromium on this machine")
    path, _ = certificate
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
           "--disable-component-update", "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}",
           "--proxy-server=127.0.0.1:9", "--virtual-time-budget=5000", "--dump-dom", path.as_uri()]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    dom = res.stdout
    assert "relate only to the item calibrated" in dom, res.stderr[-500:]
    assert "<svg" in dom and "<path" in dom
