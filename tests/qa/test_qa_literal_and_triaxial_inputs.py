"""User strings in plots are literal; triaxial inputs as they come (headerless, logger preambles)."""

from __future__ import annotations

import json

import numpy as np

from senscal.report.plots import new_figure, save_figure, svg_inline


def test_tex_like_strings_are_drawn_literally(tmp_path):
    fig, ax = new_figure()
    ax.plot([0, 1], [0, 1])
    ax.set_ylabel("output ($\\frac{$)")
    ax.set_title("$x^{$ [/bold] _$")
    assert save_figure(fig, tmp_path / "p.png").stat().st_size > 0
    assert "<svg" in svg_inline(fig)


def _sphere_readings(n=300):
    rng = np.random.default_rng(0)
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1)[:, None] * [50.0, 45.0, 55.0] + [3.0, -2.0, 1.0]


def test_triaxial_headerless_xyz_needs_no_fs(cli, tmp_path):
    f = tmp_path / "xyz.csv"
    np.savetxt(f, _sphere_readings(), delimiter=",")
    r = cli("triaxial", "calibrate", f, "--names", "x,y,z", "--channels", "x,y,z", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["channels"] == ["x", "y", "z"]
    r = cli("triaxial", "calibrate", f, "--names", "x,y,z", "--channels", "x,y,z", "--static")
    assert r.code == 2 and "no time column" in r.err and len(r.err.splitlines()) == 1


def test_triaxial_logger_preamble_auto_and_skip_rows(cli, tmp_path):
    body = "\n".join(",".join(f"{v:.6f}" for v in row) for row in _sphere_readings())
    auto = tmp_path / "qmc.csv"
    auto.write_text("Fs,50.00\nInitialization time,60\nmx,my,mz\n" + body + "\n")
    r = cli("triaxial", "calibrate", auto, "--channels", "mx,my,mz", "--json")
    assert r.code == 0, r.err
    free = tmp_path / "free.csv"
    free.write_text("exported by logger v2\nunit uT\nmx,my,mz\n" + body + "\n")
    r = cli("triaxial", "calibrate", free, "--channels", "mx,my,mz", "--skip-rows", "2", "--json")
    assert r.code == 0, r.err
