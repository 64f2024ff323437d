"""The Kalman engine against filterpy / pykalman / scipy on the same model."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FPKalman
from hypothesis import given, settings
from hypothesis import strategies as st
from pykalman import KalmanFilter as PKKalman
from scipy.stats import multivariate_normal

from senscal.errors import DataError, InputError
from senscal.kalman import StateSpaceModel, fixed_lag_smoother, kalman_filter, log_likelihood, rts_smoother

RTOL = 1e-9


def close(a, b, rtol=RTOL):
    """Agreement to ``rtol`` relative to the array's scale."""
    a, b = np.asarray(a), np.asarray(b)
    scale = max(np.max(np.abs(b)), 1e-300)
    return np.max(np.abs(a - b)) <= rtol * scale


def cv_model(dt=0.01, q=100.0, r=0.1, with_b=False):
    """4-state constant-velocity model in 2-D, 2 position measurements."""
    F = np.array([[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1.0]])
    H = np.array([[1, 0, 0, 0], [0, 0, 1, 0.0]])
    G = np.array([[dt**2 / 2, 0], [dt, 0], [0, dt**2 / 2], [0, dt]])
    Q = q * G @ G.T + 1e-9 * np.eye(4)
    R = np.array([[r, 0.02], [0.02, 2 * r]])
    B = G if with_b else None
    return StateSpaceModel(F, H, Q, R, B=B, x0=np.array([0.5, 0, -0.2, 0]), P0=np.diag([4.0, 1, 4, 1]))


def simulate(model, T, rng, u=None):
    n, m = model.n_states, model.n_measurements
    x = rng.multivariate_normal(model.x0, model.P0)
    ys = np.empty((m, T))
    F, H, Q, R = (np.broadcast_to(a, (T,) + a.shape[-2:]) if a.ndim == 2 else a
                  for a in (model.F, model.H, model.Q, model.R))
    for t in range(T):
        if t > 0:
            x = F[t] @ x + rng.multivariate_normal(np.zeros(n), Q[t])
            if u is not None:
                x = x + model.B @ u[:, t - 1]
        ys[:, t] = H[t] @ x + rng.multivariate_normal(np.zeros(m), R[t])
    return ys


def filterpy_run(model, y, u=None, F_t=None, H_t=None):
    """filterpy's loop, one measurement per step; NaN components dropped."""
    n, m = model.n_states, model.n_measurements
    kf = FPKalman(dim_x=n, dim_z=m, dim_u=model.n_inputs if u is not None else 0)
    kf.F, kf.Q = model.F, model.Q
    if u is not None:
        kf.B = model.B
    kf.x = model.x0.reshape(-1, 1).copy()
    kf.P = model.P0.copy()
    out = {k: [] for k in ("x", "P", "xp", "Pp")}
    ll = 0.0
    for t in range(y.shape[1]):
        if t > 0:
            if F_t is not None:
                kf.F = F_t[t]
            kf.predict(u=None if u is None else u[:, t - 1:t])
        out["xp"].append(kf.x[:, 0].copy())
        out["Pp"].append(kf.P.copy())
        H = model.H if H_t is None else H_t[t]
        obs = ~np.isnan(y[:, t])
        if obs.any():
            kf.H = H[obs]
            kf.R = model.R[np.ix_(obs, obs)]
            kf.dim_z = int(obs.sum())
            kf.update(y[obs, t:t + 1])
            ll += kf.log_likelihood
        out["x"].append(kf.x[:, 0].copy())
        out["P"].append(kf.P.copy())
    return {k: np.moveaxis(np.array(v), 0, -1) for k, v in out.items()}, ll


@pytest.mark.parametrize("steady", [True, False])
def test_filter_matches_filterpy_with_control(steady):
    rng = np.random.default_rng(1)
    model = cv_model(with_b=True)
    T = 3000
    u = rng.normal(size=(2, T))
    y = simulate(model, T, rng, u)
    res = kalman_filter(model, y, u, steady_state=steady)
    if steady:
        assert res.steady_state_from > 0  # the frozen-gain path was taken
    ref, ll = filterpy_run(model, y, u)
    assert close(res.x, ref["x"]) and close(res.P, ref["P"])
    assert close(res.x_pred, ref["xp"]) and close(res.P_pred, ref["Pp"])
    assert res.loglik == pytest.approx(ll, rel=RTOL)


def test_smoother_matches_pykalman():
    rng = np.random.default_rng(2)
    model = cv_model()
    y = simulate(model, 800, rng)
    pk = PKKalman(transition_matrices=model.F, observation_matrices=model.H, transition_covariance=model.Q,
                  observation_covariance=model.R, initial_state_mean=model.x0, initial_state_covariance=model.P0)
    mu_f, cov_f = pk.filter(y.T)
    mu_s, cov_s = pk.smooth(y.T)
    res = kalman_filter(model, y)
    sm = rts_smoother(model, res)
    assert close(res.x, mu_f.T) and close(res.P, np.moveaxis(cov_f, 0, -1))
    assert close(sm.x, mu_s.T) and close(sm.P, np.moveaxis(cov_s, 0, -1))
    assert pk.loglikelihood(y.T) == pytest.approx(res.loglik, rel=RTOL)
    # Same smoother when the function filters itself.
    assert np.array_equal(rts_smoother(model, y).x, sm.x)


def test_missing_components_match_filterpy_reduced_update():
    rng = np.random.default_rng(3)
    model = cv_model()
    y = simulate(model, 500, rng)
    y[0, rng.random(500) < 0.2] = np.nan
    y[1, rng.random(500) < 0.2] = np.nan
    y[:, 100:110] = np.nan
    res = kalman_filter(model, y)
    assert res.steady_state_from == -1
    ref, ll = filterpy_run(model, y)
    assert close(res.x, ref["x"]) and close(res.P, ref["P"])
    assert res.loglik == pytest.approx(ll, rel=RTOL)
    assert np.array_equal(np.isnan(res.normalized_innovation), np.isnan(y))


def test_time_varying_matrices_match_filterpy():
    rng = np.random.default_rng(4)
    base = cv_model()
    T = 400
    tt = np.arange(T)
    F_t = np.repeat(base.F[None], T, 0)
    F_t[:, 0, 1] = F_t[:, 2, 3] = 0.01 * (1 + 0.5 * np.sin(tt / 30))
    H_t = np.repeat(base.H[None], T, 0)
    H_t[:, 0, 1] = np.cos(tt / 17)
    model = base.replace(F=F_t, H=H_t)
    assert model.time_varying and model.n_steps == T
    y = simulate(model, T, rng)
    res = kalman_filter(model, y)
    ref, ll = filterpy_run(model, y, F_t=F_t, H_t=H_t)
    assert close(res.x, ref["x"]) and close(res.P, ref["P"])
    assert res.loglik == pytest.approx(ll, rel=RTOL)
    sm = rts_smoother(model, res)
    pk = PKKalman(transition_matrices=F_t[1:], observation_matrices=H_t, transition_covariance=model.Q,
                  observation_covariance=model.R, initial_state_mean=model.x0, initial_state_covariance=model.P0)
    mu_s, cov_s = pk.smooth(y.T)
    assert close(sm.x, mu_s.T) and close(sm.P, np.moveaxis(cov_s, 0, -1))


def test_loglik_equals_joint_gaussian_density():
    """Independent oracle: the stacked measurements are jointly Gaussian."""
    rng = np.random.default_rng(5)
    model = StateSpaceModel(F=[[0.9, 0.1], [0, 0.95]], H=[[1.0, 0.5]], Q=np.diag([0.1, 0.05]), R=[[0.3]],
                            x0=[1.0, -1.0], P0=np.diag([0.5, 0.2]))
    T = 12
    y = simulate(model, T, rng)
    # Stacked state covariance via the transition powers.
    n = 2
    Fp = [np.eye(n)]
    for _ in range(T):
        Fp.append(model.F @ Fp[-1])
    mean = np.array([(model.H @ Fp[t] @ model.x0)[0] for t in range(T)])
    cov = np.empty((T, T))
    for s in range(T):
        for t in range(T):
            lo = min(s, t)
            c = Fp[s] @ model.P0 @ Fp[t].T
            for j in range(1, lo + 1):
                c += Fp[s - j] @ model.Q @ Fp[t - j].T
            cov[s, t] = (model.H @ c @ model.H.T)[0, 0] + (model.R[0, 0] if s == t else 0)
    ll = multivariate_normal(mean, cov).logpdf(y[0])
    assert kalman_filter(model, y).loglik == pytest.approx(ll, rel=1e-10)


def test_batch_equals_single_series():
    rng = np.random.default_rng(6)
    model = cv_model()
    ys = np.stack([simulate(model, 300, rng) for _ in range(3)])
    ys[1, 0, 50] = np.nan  # one series on the general path, the others steady
    res = kalman_filter(model, ys)
    sm = rts_smoother(model, res)
    assert res.x.shape == (3, 4, 300) and res.P.shape == (3, 4, 4, 300) and res.loglik.shape == (3,)
    for s in range(3):
        one = kalman_filter(model, ys[s])
        assert np.allclose(res.x[s], one.x, rtol=0, atol=0)
        assert res.loglik[s] == one.loglik
        assert np.array_equal(sm.x[s], rts_smoother(model, one).x)


def test_gate_rejects_outlier_like_a_missing_sample():
    rng = np.random.default_rng(7)
    model = cv_model()
    y = simulate(model, 400, rng)
    y[0, 200] += 50.0  # 50 / sqrt(0.1) ~ 160 sigma
    res = kalman_filter(model, y, gate=30.0)
    assert res.rejected[200] and res.rejected.sum() <= 2
    y_nan = y.copy()
    y_nan[:, res.rejected] = np.nan
    ref = kalman_filter(model, y_nan)
    assert close(res.x, ref.x, 1e-12)
    assert res.normalized_innovation[0, 200] > 30


def test_normalized_innovations_are_white_unit_variance():
    rng = np.random.default_rng(8)
    model = cv_model()
    T = 4000
    e = kalman_filter(model, simulate(model, T, rng)).normalized_innovation[:, 10:]
    N = e.size
    # Sample mean and variance of N standard normals: sd 1/sqrt(N) and sqrt(2/N).
    assert abs(e.mean()) < 4 / np.sqrt(N)
    assert abs((e**2).mean() - 1) < 4 * np.sqrt(2 / N)
    lag1 = np.mean(e[:, 1:] * e[:, :-1])
    assert abs(lag1) < 4 / np.sqrt(N)


def test_fixed_lag_between_filter_and_smoother():
    rng = np.random.default_rng(9)
    model = cv_model()
    y = simulate(model, 300, rng)
    res = kalman_filter(model, y)
    sm = rts_smoother(model, res)
    assert np.allclose(fixed_lag_smoother(model, res, 0).x, res.x, rtol=0, atol=0)
    assert close(fixed_lag_smoother(model, res, 299).x, sm.x, 1e-12)
    v = [np.trace(fixed_lag_smoother(model, res, L).P[..., 150]) for L in (0, 2, 10, 50)]
    assert all(a >= b for a, b in zip(v, v[1:]))  # more look-ahead, less variance
    # Past t + lag the data cannot matter.
    y2 = y.copy()
    y2[:, 200:] += 3.0
    fl1 = fixed_lag_smoother(model, y, 10)
    fl2 = fixed_lag_smoother(model, y2, 10)
    assert np.array_equal(fl1.x[:, :190], fl2.x[:, :190])


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(1, 3), st.floats(1e-6, 1e2), st.floats(1e-4, 1e2))
def test_covariances_stay_symmetric_psd(seed, n, m, q, r):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    F = A / max(1.0, np.max(np.abs(np.linalg.eigvals(A)))) * 1.02
    H = rng.normal(size=(m, n))
    Q = q * np.diag(rng.random(n))
    R = r * np.eye(m)
    model = StateSpaceModel(F, H, Q, R)
    y = rng.normal(size=(m, 200))
    res = kalman_filter(model, y, steady_state=False)
    for P in (res.P, rts_smoother(model, res).P):
        Pt = np.moveaxis(P, -1, 0)
        assert np.array_equal(Pt, np.swapaxes(Pt, 1, 2))
        w = np.linalg.eigvalsh(Pt)
        assert np.all(w >= -1e-9 * np.max(np.abs(Pt), axis=(1, 2))[:, None])


@pytest.mark.parametrize("kw, msg", [
    (dict(Q=[[1.0, 0.5], [0.0, 1.0]]), "Q must be symmetric"),
    (dict(R=[[-1.0]]), "R must be positive definite"),
    (dict(H=[[1.0, 0.0, 0.0]]), "H must have shape"),
    (dict(F=[[1.0, np.nan], [0.0, 1.0]]), "NaN"),
    (dict(x0=[1.0]), "x0 must be 2"),
])
def test_invalid_models_raise_one_line_input_error(kw, msg):
    base = dict(F=np.eye(2), H=[[1.0, 0.0]], Q=np.eye(2), R=[[1.0]])
    base.update(kw)
    with pytest.raises(InputError, match=msg):
        StateSpaceModel(**base)


def test_invalid_measurements():
    model = StateSpaceModel(F=np.eye(2), H=[[1.0, 0.0]], Q=np.eye(2), R=[[1.0]])
    with pytest.raises(InputError, match="y must have shape"):
        kalman_filter(model, np.zeros((2, 10)))
    with pytest.raises(DataError, match="inf"):
        kalman_filter(model, np.array([[0.0, np.inf]]))
    with pytest.raises(InputError, match="no control matrix"):
        kalman_filter(model, np.zeros((1, 10)), np.zeros((1, 10)))
    with pytest.raises(InputError, match="gate"):
        kalman_filter(model, np.zeros((1, 10)), gate=-1.0)


def test_log_likelihood_only_pass_equals_filter():
    rng = np.random.default_rng(10)
    model = cv_model()
    y = simulate(model, 2000, rng)
    assert log_likelihood(model, y) == pytest.approx(kalman_filter(model, y).loglik, rel=1e-13)
    y[1, 5] = np.nan
    assert log_likelihood(model, y) == pytest.approx(kalman_filter(model, y).loglik, rel=1e-13)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(1e-3, 1e3))
def test_unit_change_scales_estimates(seed, s):
    """Measuring in other units (y -> s y) scales states by s, covariances by s^2."""
    rng = np.random.default_rng(seed)
    model = cv_model()
    y = simulate(model, 150, rng)
    y[0, rng.random(150) < 0.1] = np.nan
    scaled = model.replace(Q=s**2 * model.Q, R=s**2 * model.R, x0=s * model.x0, P0=s**2 * model.P0)
    a = kalman_filter(model, y)
    b = kalman_filter(scaled, s * y)
    assert close(b.x, s * a.x, 1e-9) and close(b.P, s**2 * a.P, 1e-9)
    assert np.allclose(b.normalized_innovation, a.normalized_innovation, rtol=1e-7, atol=1e-9, equal_nan=True)
    n_obs = np.isfinite(y).sum()
    assert b.loglik == pytest.approx(a.loglik - n_obs * np.log(s), rel=1e-9, abs=1e-7)
    sa, sb = rts_smoother(model, a), rts_smoother(scaled, b)
    assert close(sb.x, s * sa.x, 1e-9)


def test_a_built_model_skips_only_the_eigenvalue_test_of_q():
    """StateSpaceModel._built (issue 30): the same model as the constructor's; bad shapes, R and Q's diagonal refused."""
    rng = np.random.default_rng(2)
    Q = np.einsum("tij,tkj->tik", *(2 * [rng.normal(size=(50, 2, 2))]))
    F, H, R = np.eye(2), np.ones((1, 2)), np.array([[0.1]])
    a = StateSpaceModel(F=F, H=H, Q=Q, R=R, P0=np.eye(2))
    b = StateSpaceModel._built(F=F, H=H, Q=Q, R=R, P0=np.eye(2))
    for k in ("_F", "_H", "_Q", "_R", "_B", "x0", "P0"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    y = rng.normal(size=(1, 50))
    assert kalman_filter(a, y).loglik == kalman_filter(b, y).loglik
    bad_q = Q.copy()
    bad_q[7, 1, 1] = -1e-3
    with pytest.raises(InputError, match="Q must be positive semidefinite"):
        StateSpaceModel._built(F=F, H=H, Q=bad_q, R=R)
    with pytest.raises(InputError, match="R must be positive definite"):
        StateSpaceModel._built(F=F, H=H, Q=Q, R=np.array([[0.0]]))
    with pytest.raises(InputError, match="H must have shape"):
        StateSpaceModel._built(F=F, H=np.ones((1, 3)), Q=Q, R=R)
    with pytest.raises(InputError, match="NaN or inf"):
        StateSpaceModel._built(F=F, H=H, Q=np.full((2, 2), np.nan), R=R)
