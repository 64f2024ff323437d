"""The registry's web view in a real browser (Playwright driving Debian's Chromium; issue 29).

A person opens the sensor list, clicks a sensor, clicks one of its
calibrations and downloads the certificate; the same with the keyboard
only; and the pages at 80 % zoom.  Playwright's own browser download is not
reachable from these machines, so the system Chromium is driven through
``executable_path`` (CI installs Debian's ``chromium``, see ``.ci/run``).
"""

from __future__ import annotations

import os
import shutil
import threading

import pytest

from senscal.registry import Quantity, open_registry


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _need(what: str, why: str):
    if os.environ.get("CI"):
        pytest.fail(f"CI must provide {what} for the web view's browser test: {why}")
    pytest.skip(f"no {what} on this machine: {why}")


@pytest.fixture(scope="module")
def browser():
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _need("playwright", "pip install '.[test]' installs it")
    exe = _chromium()
    if exe is None:
        _need("chromium", "apt-get install chromium")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe, args=["--no-sandbox", "--disable-gpu"])
        try:
            yield b
        finally:
            b.close()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    from senscal.registry.web import ViewOptions, create_app, make_server, open_read_only

    d = tmp_path_factory.mktemp("web")
    reg = open_registry(d / "lab.sqlite")
    reg.add_sensor("A1", "accelerometer", model="4371")
    reg.add_sensor("B2", "velocity sensor")
    reg.add_standard("REF-1", certificate="DKD-K-1/2023", due="2030-01-31", u_relative="0.2%")
    recs = []
    for i, year in enumerate(range(2021, 2024)):
        pdf = d / f"A1-{year}.pdf"
        pdf.write_bytes(b"%PDF-1.4 certificate of A1, " + str(year).encode())
        recs.append(reg.record("A1", [Quantity("sensitivity", 0.0100 + 2e-5 * i, 1e-6, "V/(m/s^2)", 2.0)],
                               performed_at=f"{year}-03-01", certificate=pdf, standards=["REF-1"]))
    reg.close()
    ro = open_read_only(d / "lab.sqlite")
    srv = make_server(create_app(ro, ViewOptions(tolerance=0.01)), "127.0.0.1", 0)
    thread = threading.Thread(target=srv.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{srv.port}", recs, d
    finally:
        srv.shutdown()
        srv.server_close()
        ro.close()


@pytest.fixture
def page(browser, server, tmp_path):
    base = server[0]
    context = browser.new_context(accept_downloads=True, viewport={"width": 1280, "height": 900})
    pg = context.new_page()
    pg.set_default_timeout(30_000)
    requests: list[str] = []
    pg.on("request", lambda req: requests.append(req.url))
    yield pg
    context.close()
    # Every request went to the view itself (data: URIs are inline): nothing from the network.
    assert requests and all(u.startswith(base + "/") or u.startswith("data:") for u in requests), requests


def test_click_from_sensor_list_to_a_calibration_and_download_its_certificate(page, server, tmp_path):
    base, recs, folder = server
    page.goto(base + "/")
    page.get_by_role("link", name="A1", exact=True).click()
    page.wait_for_url(base + "/sensors/A1")
    assert page.get_by_role("heading", level=1).inner_text() == "Sensor A1"
    last = recs[-1]
    page.get_by_role("link", name=last.uid[:8]).click()
    page.wait_for_url(f"{base}/calibrations/{last.uid}")
    with page.expect_download() as info:
        page.get_by_role("link", name="Download the PDF certificate").click()
    download = info.value
    assert download.suggested_filename == "A1-2023.pdf"
    saved = tmp_path / download.suggested_filename
    download.save_as(saved)
    assert saved.read_bytes() == (folder / "A1-2023.pdf").read_bytes()
    # And back to the standard it used, and from there to the impact list.
    page.get_by_role("link", name="REF-1").click()
    page.wait_for_url(base + "/standards/REF-1")
    assert page.get_by_role("link", name=recs[0].uid[:8]).count() == 1


def test_keyboard_only(page, server):
    base, recs, _ = server
    page.goto(base + "/")
    page.keyboard.press("Tab")
    focused = page.evaluate("() => document.activeElement.textContent.trim()")
    assert focused == "Skip to content"
    # The focused link is visibly marked (an outline), not only by the browser's default.
    outline = page.evaluate("() => getComputedStyle(document.activeElement).outlineStyle")
    assert outline not in ("", "none")
    # Tab through the page to the sensor A1 and open it with Enter.
    for _ in range(30):
        page.keyboard.press("Tab")
        if page.evaluate("() => document.activeElement.textContent.trim()") == "A1":
            break
    else:
        pytest.fail("Tab never reached the link of sensor A1")
    page.keyboard.press("Enter")
    page.wait_for_url(base + "/sensors/A1")
    target = recs[0].uid[:8]
    for _ in range(40):
        page.keyboard.press("Tab")
        if page.evaluate("() => document.activeElement.textContent.trim()") == target:
            break
    else:
        pytest.fail("Tab never reached the first calibration's link")
    page.keyboard.press("Enter")
    page.wait_for_url(f"{base}/calibrations/{recs[0].uid}")
    with page.expect_download() as info:
        for _ in range(20):
            page.keyboard.press("Tab")
            if page.evaluate("() => document.activeElement.textContent.trim()") == "Download the PDF certificate":
                break
        page.keyboard.press("Enter")
    assert info.value.suggested_filename == "A1-2021.pdf"


@pytest.mark.parametrize("window", [(1280, 800), (900, 700)])
def test_pages_at_80_percent_zoom(browser, server, window):
    """At 80 % zoom a window shows 1.25 times the CSS pixels: nothing may spill sideways or vanish."""
    base, recs, _ = server
    w, h = window
    context = browser.new_context(viewport={"width": round(w / 0.8), "height": round(h / 0.8)},
                                  device_scale_factor=0.8)
    pg = context.new_page()
    try:
        for path in ("/", "/sensors/A1", f"/calibrations/{recs[-1].uid}", "/standards/REF-1", "/chain"):
            pg.goto(base + path)
            over = pg.evaluate("() => document.documentElement.scrollWidth - document.documentElement.clientWidth")
            assert over <= 0, (path, window, over)
            body_font = pg.evaluate("() => parseFloat(getComputedStyle(document.body).fontSize)")
            assert body_font >= 16  # 12.8 device pixels at 80 %: the browser's default, not smaller
            if path == "/sensors/A1":
                box = pg.locator("figure svg").first.bounding_box()
                assert box and 0 < box["width"] <= round(w / 0.8)
    finally:
        context.close()
