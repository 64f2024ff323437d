"""The demo report opens in a real headless browser with no broken images or links."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

CHECK = """<script>
window.addEventListener('load', function () {
  var bad = [];
  for (var i = 0; i < document.images.length; i++) {
    var im = document.images[i];
    if (!(im.complete && im.naturalWidth > 0)) bad.push(im.getAttribute('alt') || 'image ' + i);
  }
  document.body.setAttribute('data-images', String(document.images.length));
  document.body.setAttribute('data-broken', JSON.stringify(bad));
});
</script>"""


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    from senscal.demo import run_demo

    out = tmp_path_factory.mktemp("demo")
    sections, index = run_demo(out, seed=1)
    return out, sections, index


def test_index_lists_every_job(demo_dir):
    from senscal.demo import discover

    out, sections, index = demo_dir
    assert len(sections) == len(discover())
    html = index.read_text()
    for s in sections:
        assert f'id="{s.key}"' in html


def test_links_and_resources_are_local(demo_dir):
    out, sections, index = demo_dir
    html = index.read_text()
    assert not re.search(r'(src|href)="(https?:)?//', html), "the report must not load anything from the network"
    ids = set(re.findall(r'id="([^"]+)"', html))
    for href in re.findall(r'href="([^"]+)"', html):
        if href.startswith("#"):
            assert href[1:] in ids, f"dangling anchor {href}"
        else:
            assert (out / href).is_file(), f"broken link {href}"


def test_headless_browser_finds_no_broken_images(demo_dir, tmp_path):
    exe = _chromium()
    if exe is None:
        if os.environ.get("CI"):
            pytest.fail("CI must install Debian's chromium for the demo page test")
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    out, sections, index = demo_dir
    page = out / "_browser_check.html"
    page.write_text(index.read_text().replace("</body>", CHECK + "</body>"))
    profile = tmp_path / "profile"
    cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={profile}", "--virtual-time-budget=10000", "--dump-dom", page.as_uri()]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    dom = res.stdout
    m = re.search(r'data-images="(\d+)"', dom)
    assert m, f"page did not finish loading in the browser: {res.stderr[-500:]}"
    broken = re.search(r"data-broken=\"([^\"]*)\"", dom).group(1).replace("&quot;", '"')
    assert json.loads(broken) == []
    assert int(m.group(1)) >= sum(1 for s in sections if s.plot)
