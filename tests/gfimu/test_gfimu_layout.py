"""Array kinematics: exact solve, degenerate layouts, layout files, noise propagation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st

from senscal.errors import DegenerateGeometryError, FileFormatError, InputError
from senscal.gfimu import Layout, paper_layout, read_layout, solve_kinematics, write_layout


def readings_of(layout: Layout, f, alpha, w):
    """Rigid-body readings computed directly with cross products (independent of the design matrix)."""
    out = np.empty((layout.n_channels, f.shape[1]))
    for k in range(f.shape[1]):
        for i, (r, n) in enumerate(zip(layout.positions, layout.directions)):
            out[i, k] = n @ (f[:, k] + np.cross(alpha[:, k], r) + np.cross(w[:, k], np.cross(w[:, k], r)))
    return out


def random_layout(rng, m=12, scale=0.05):
    return Layout(tuple(f"c{i}" for i in range(m)), rng.normal(0, scale, (m, 3)), rng.normal(0, 1, (m, 3)))


@given(st.integers(0, 10_000), st.integers(12, 20))
def test_exact_solve_random_layout(seed, m):
    rng = np.random.default_rng(seed)
    lay = random_layout(rng, m)
    T = 5
    f, alpha, w = rng.normal(0, 10, (3, T)), rng.normal(0, 50, (3, T)), rng.normal(0, 5, (3, T))
    try:
        sol = solve_kinematics(readings_of(lay, f, alpha, w), lay)
    except DegenerateGeometryError:
        # A random layout can be (nearly) degenerate; then the refusal must be justified.
        As = lay.design / np.linalg.norm(lay.design, axis=0)
        assert np.linalg.cond(As) > 1e7
        return
    # Rounding grows with the condition number: allow eps * cond * a margin.
    tol = 1e-13 * sol.condition_number * 100
    np.testing.assert_allclose(sol.specific_force, f, rtol=0, atol=tol * 100)
    np.testing.assert_allclose(sol.angular_acceleration, alpha, rtol=0, atol=tol * 1000)
    np.testing.assert_allclose(sol.squares, w ** 2, rtol=0, atol=tol * 100)
    np.testing.assert_allclose(sol.products, np.stack([w[0] * w[1], w[0] * w[2], w[1] * w[2]]), rtol=0, atol=tol * 100)


def test_paper_layout_matches_closed_form():
    # METHODS.md 2b: dwz/dt = (d2_y - d3_x) / (2L), wx wy = (d2_y + d3_x) / (2L), d2_x = -L (wy^2 + wz^2)
    L = 0.04
    lay = paper_layout(L)
    rng = np.random.default_rng(3)
    f, alpha, w = rng.normal(0, 10, (3, 4)), rng.normal(0, 50, (3, 4)), rng.normal(0, 5, (3, 4))
    a = readings_of(lay, f, alpha, w)
    ch = dict(zip(lay.names, a))
    d2y, d3x, d2x = ch["a2y"] - ch["a1y"], ch["a3x"] - ch["a1x"], ch["a2x"] - ch["a1x"]
    sol = solve_kinematics(a, lay)
    np.testing.assert_allclose(sol.angular_acceleration[2], (d2y - d3x) / (2 * L), rtol=1e-12)
    np.testing.assert_allclose(sol.products[0], (d2y + d3x) / (2 * L), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sol.x[6], d2x / L, rtol=1e-12)
    assert lay.names[0] == "a1x" and lay.names[-1] == "a4z"


def test_coplanar_layout_refused():
    rng = np.random.default_rng(0)
    pos = rng.normal(0, 0.05, (12, 3))
    pos[:, 2] = 0.0  # every sensor in the z = 0 plane
    lay = Layout(tuple(f"c{i}" for i in range(12)), pos, rng.normal(0, 1, (12, 3)))
    with pytest.raises(DegenerateGeometryError, match="cannot sense W_zz"):
        solve_kinematics(np.zeros((12, 3)), lay)


def test_tilted_plane_and_too_few_refused():
    rng = np.random.default_rng(1)
    uv = rng.normal(0, 0.05, (14, 2))
    e1, e2 = np.array([1.0, 1.0, 0.0]) / np.sqrt(2), np.array([0.0, 1.0, 1.0]) / np.sqrt(2)
    pos = uv[:, :1] * e1 + uv[:, 1:] * e2  # coplanar but not along an axis: only the rank shows it
    lay = Layout(tuple(f"c{i}" for i in range(14)), pos, rng.normal(0, 1, (14, 3)))
    with pytest.raises(DegenerateGeometryError, match="condition number"):
        solve_kinematics(np.zeros((14, 2)), lay)
    few = Layout(("a", "b"), np.eye(3)[:2], np.eye(3)[:2])
    with pytest.raises(DegenerateGeometryError, match="at least 12"):
        solve_kinematics(np.zeros((2, 2)), few)


@given(st.floats(1e-3, 10.0))
def test_condition_number_is_scale_free(L):
    assert solve_kinematics(np.zeros((12, 1)), paper_layout(L)).condition_number == pytest.approx(
        solve_kinematics(np.zeros((12, 1)), paper_layout(0.04)).condition_number, rel=1e-9)


def test_noise_propagation_matches_monte_carlo():
    lay = paper_layout(0.04)
    rng = np.random.default_rng(5)
    sigma = 0.01
    n = 20000
    sol = solve_kinematics(rng.normal(0, sigma, (12, n)), lay)
    var_mc = sol.x.var(axis=1)
    var_th = sigma ** 2 * np.diag(sol.unit_covariance)
    # Sample variance of n Gaussian draws has relative std sqrt(2/n) ~ 1 %; 5 sigma.
    np.testing.assert_allclose(var_mc, var_th, rtol=5 * np.sqrt(2 / n))


def test_layout_file_roundtrip_and_errors(tmp_path):
    rng = np.random.default_rng(2)
    lay = random_layout(rng, 13)
    p = write_layout(lay, tmp_path / "lay.csv")
    back = read_layout(p)
    assert back.names == lay.names
    np.testing.assert_array_equal(back.positions, lay.positions)
    np.testing.assert_allclose(back.directions, lay.directions, rtol=1e-15)
    bad = tmp_path / "bad.csv"
    bad.write_text("name,x,y,z\nq,1,2,3\n")
    with pytest.raises(FileFormatError, match="nx"):
        read_layout(bad)
    bad.write_text("name,x,y,z,nx,ny,nz\nq,1,2,3,0,0,zero\n")
    with pytest.raises(FileFormatError, match="line 2"):
        read_layout(bad)
    with pytest.raises(InputError, match="zero sensitive direction"):
        Layout(("a",), [[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(InputError, match="positive"):
        paper_layout(-1.0)


@given(st.integers(0, 10_000))
def test_channel_order_does_not_matter(seed):
    rng = np.random.default_rng(seed)
    lay = paper_layout(0.04)
    y = rng.normal(0, 1, (12, 3))
    perm = rng.permutation(12)
    shuffled = Layout(tuple(np.array(lay.names)[perm]), lay.positions[perm], lay.directions[perm])
    np.testing.assert_allclose(solve_kinematics(y[perm], shuffled).x, solve_kinematics(y, lay).x, rtol=1e-10, atol=1e-10)


def test_redundant_layout_residual_measures_noise():
    # 24 channels: two paper arrays, the second rotated 45 deg about z; the residual RMS
    # (corrected for the 12 fitted unknowns) must estimate the channel noise.
    a = paper_layout(0.05)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    lay = Layout(a.names + tuple(n + "r" for n in a.names), np.vstack([a.positions, a.positions @ rot.T + 0.01]),
                 np.vstack([a.directions, a.directions @ rot.T]))
    rng = np.random.default_rng(0)
    sigma, n = 0.02, 4000
    f, alpha, w = rng.normal(0, 5, (3, n)), rng.normal(0, 20, (3, n)), rng.normal(0, 3, (3, n))
    y = readings_of_fast(lay, f, alpha, w) + rng.normal(0, sigma, (24, n))
    sol = solve_kinematics(y, lay)
    # Mean of n residual variances, each with 12 degrees of freedom: relative std sqrt(2/(12 n)) ~ 0.4 %.
    assert np.sqrt(np.mean(sol.residual_rms ** 2)) == pytest.approx(sigma, rel=5 * np.sqrt(2 / (12 * n)))


def readings_of_fast(layout, f, alpha, w):
    acc = (f.T[:, None, :] + np.cross(alpha.T[:, None, :], layout.positions[None])
           + np.cross(w.T[:, None, :], np.cross(w.T[:, None, :], layout.positions[None])))
    return np.einsum("tmi,mi->mt", acc, layout.directions)
