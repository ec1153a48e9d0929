"""Tests of :mod:`hmpc_pin.compensation.observers` on the planar three-link arm
(``robots/planar3.urdf``).

The observer is checked against its error dynamics, computed here independently:

* Eq (29): ``L M = c Y`` with ``Y`` the lower-triangular matrix of ones (Chen) or ``I``.
* Eq (18): for a constant disturbance the error ``w = d - d̂`` obeys ``ẇ = -L(q) w``.
  With the arm held at rest (``τ = G(q) - d`` so that ``M q̈ = 0``) ``L`` is constant, the
  backward-Euler observer must give exactly ``w_k = (I + Ts L)^{-k} w_0`` and the explicit
  one ``w_k = (I - Ts L)^k w_0`` (matrix powers computed with numpy), and as ``Ts → 0``
  both approach ``exp(-L t) w_0`` (``scipy.linalg.expm``) at first order in ``Ts``.
* On a moving arm, the plant is integrated here with RK4 at 0.1 ms under a PD law (the
  observer is never used for control) and ``ẇ = -L(q(t)) w`` is integrated along the same
  trajectory with the same RK4; the sampled observer must follow it, again at first order
  in its sampling period.

``L`` is formed here as ``c Y inv(M)`` with ``numpy.linalg.inv``; the observer's own
``gain_matrix`` is only used in the test of Eq (29) itself.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from hmpc_pin.compensation.observers import DisturbanceObserver
from hmpc_pin.model.robot import Robot, load_robot

URDF = Path(__file__).resolve().parents[1] / "robots" / "planar3.urdf"
N_JOINTS = 3
#: Eq (28), written out.
Y_CHEN = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 1.0, 1.0]])
Y_OF = {"chen": Y_CHEN, "general": np.eye(N_JOINTS)}
KINDS = tuple(Y_OF)
Q_LIMIT = np.array([np.pi / 2, np.pi / 2, 3 * np.pi / 4])
#: The outer-loop acceleration held over the last period, the last argument of
#: ``Compensation.update``; the observers do not use it, and no outer loop runs here.
NO_V = np.zeros(N_JOINTS)


# --------------------------------------------------------------------- helpers
def own_gain(c: float, Y: np.ndarray, M: np.ndarray) -> np.ndarray:
    """L = c Y M^{-1} (Eq 30), independently of the package."""
    return c * Y @ np.linalg.inv(M)


def observe_at_rest(robot: Robot, obs: DisturbanceObserver, q, d, steps: int) -> np.ndarray:
    """Hold the arm at ``q`` with τ = G(q) - d, feed the observer; return w_0 .. w_steps.

    With that torque the plant's acceleration (ABA with the true disturbance) is zero, so
    q and q̇ = 0 stay constant; this is checked rather than integrated, because the upright
    equilibria of the arm are unstable and rounding would grow over many seconds.
    """
    q = np.array(q, dtype=float)
    dq = np.zeros(N_JOINTS)
    tau = robot.gravity_torque(q) - d
    assert np.abs(robot.forward_dynamics(q, dq, tau + d)).max() < 1e-9
    M, nle = robot.mass_matrix(q), robot.nonlinear_effects(q, dq)
    obs.reset(q, dq)
    errors = [d - obs.estimate]
    for _ in range(steps):
        errors.append(d - obs.update(M, nle, q, dq, tau, NO_V))
    return np.array(errors)


def rk4_step(f, y: np.ndarray, h: float, *args) -> np.ndarray:
    """One classical Runge-Kutta step of y' = f(y, *args)."""
    k1 = f(y, *args)
    k2 = f(y + 0.5 * h * k1, *args)
    k3 = f(y + 0.5 * h * k2, *args)
    k4 = f(y + h * k3, *args)
    return y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


# --------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def robot() -> Robot:
    """The planar 3-link arm, loaded once per module (read-only use)."""
    return load_robot(URDF, gravity=9.8)


@pytest.fixture
def make_poses(make_rng):
    """Factory of ``count`` random poses inside the joint ranges of Eq (27)."""

    def _make(count: int, seed: int = 0) -> list[np.ndarray]:
        rng = make_rng(seed)
        return [rng.uniform(-Q_LIMIT, Q_LIMIT) for _ in range(count)]

    return _make


@pytest.fixture
def make_observer():
    """Factory of a 3-joint observer."""

    def _make(Ts=1e-3, gain=5.0, kind="chen", discretization="implicit"):
        return DisturbanceObserver(N_JOINTS, Ts, gain, kind=kind, discretization=discretization)

    return _make


# ----------------------------------------------------------------------- Eq 28-30
def test_planar3_mass_matrix_is_not_diagonal(robot, make_poses):
    """Precondition of the Eq (29) test: M has off-diagonal terms, so Y matters."""
    for q in make_poses(5, seed=1):
        M = robot.mass_matrix(q)
        assert np.abs(M - np.diag(np.diag(M))).max() > 0.1


@pytest.mark.parametrize("kind", KINDS)
def test_gain_matrix_times_mass_matrix_is_c_y(robot, make_rng, make_poses, make_observer, kind):
    """Eq (29): L(q) M(q) = c Y for every pose."""
    rng = make_rng(2)
    for q in make_poses(10, seed=2):
        gain = rng.uniform(0.5, 50.0)
        obs = make_observer(gain=gain, kind=kind)
        M = robot.mass_matrix(q)
        L = obs.gain_matrix(M)
        np.testing.assert_allclose(L @ M, gain * Y_OF[kind], rtol=0, atol=1e-11 * gain)
        np.testing.assert_allclose(L, own_gain(gain, Y_OF[kind], M), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_p_is_c_y_dq(make_rng, make_observer, kind):
    """Eq (28): p(q̇) = c Y q̇, e.g. Chen's p = c (q̇1, q̇1 + q̇2, q̇1 + q̇2 + q̇3)."""
    rng = make_rng(3)
    obs = make_observer(gain=7.0, kind=kind)
    for _ in range(5):
        dq = rng.normal(size=N_JOINTS)
        expected = 7.0 * (np.cumsum(dq) if kind == "chen" else dq)
        np.testing.assert_allclose(obs.p(dq), expected, rtol=1e-14, atol=1e-14)


# ----------------------------------------------------------------- arm at rest
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("discretization", ["implicit", "explicit"])
def test_error_at_rest_follows_discrete_recursion(
    robot, make_rng, make_poses, make_observer, kind, discretization
):
    """w_k = (I + Ts L)^{-k} w_0 (backward Euler) or (I - Ts L)^k w_0 (forward Euler)."""
    rng = make_rng(4)
    Ts, gain, steps = 2e-3, 10.0, 150
    for q in make_poses(4, seed=4):
        d = rng.uniform(-5.0, 5.0, size=N_JOINTS)
        obs = make_observer(Ts=Ts, gain=gain, kind=kind, discretization=discretization)
        w = observe_at_rest(robot, obs, q, d, steps)
        np.testing.assert_array_equal(w[0], d)  # d̂ = 0 after reset
        L = own_gain(gain, Y_OF[kind], robot.mass_matrix(q))
        if discretization == "implicit":
            step = np.linalg.inv(np.eye(N_JOINTS) + Ts * L)
        else:
            step = np.eye(N_JOINTS) - Ts * L
        for k in (1, 2, 10, 50, steps):
            expected = np.linalg.matrix_power(step, k) @ d
            np.testing.assert_allclose(w[k], expected, rtol=0, atol=1e-10 * np.abs(d).max())
        assert np.linalg.norm(w[steps]) < 0.9 * np.linalg.norm(d)  # it does converge


@pytest.mark.parametrize("kind", KINDS)
def test_error_at_rest_approaches_continuous_solution(
    robot, make_rng, make_poses, make_observer, kind
):
    """As Ts → 0 the implicit observer error tends to exp(-L t) w_0, at first order.

    Bound: with L = V Λ V⁻¹, each mode's backward-Euler error |(1 + Ts λ)^{-k} - e^{-λ t_k}|
    is at most Ts |λ| / (2e) (1 + O(Ts λ)) < Ts ρ(L) / 2, so the vector error is below
    κ(V) · Ts ρ(L) / 2 · |w_0|. First order is checked directly: halving Ts halves the error.
    """
    rng = make_rng(5)
    gain, T = 5.0, 2.0
    for q in make_poses(3, seed=5):
        d = rng.uniform(-5.0, 5.0, size=N_JOINTS)
        L = own_gain(gain, Y_OF[kind], robot.mass_matrix(q))
        lam, V = np.linalg.eig(L)
        assert np.all(lam.real > 0)
        worst = {}
        for Ts in (1e-3, 5e-4):
            steps = round(T / Ts)
            w = observe_at_rest(robot, make_observer(Ts=Ts, gain=gain, kind=kind), q, d, steps)
            t = Ts * np.arange(steps + 1)
            exact = np.array([expm(-L * tk) @ d for tk in t[::10]])
            worst[Ts] = np.linalg.norm(w[::10] - exact, axis=1).max()
            bound = np.linalg.cond(V) * Ts * np.abs(lam).max() / 2.0 * np.linalg.norm(d)
            assert worst[Ts] < bound
        assert 1.8 < worst[1e-3] / worst[5e-4] < 2.2


# ------------------------------------------------------------------ moving arm
def test_error_on_moving_arm_follows_eq18(robot, make_rng, make_observer):
    """A PD-controlled arm under a constant disturbance: the observer follows ẇ = -L(q(t)) w.

    Plant and ``ẇ = -5 Y M(q)^{-1} w`` are integrated together by RK4 at 0.1 ms, with the
    PD torque (plus gravity compensation, no observer) held over each 1 ms control period.
    The observer samples the state every 1 ms (the paper's structure) and, for the order
    check, every 0.5 ms on the same trajectory (the torque is constant over both periods).

    Tolerance: the sampled observer is a first-order (backward Euler) discretisation of
    Eq (13), so its error differs from w(t) by O(Ts); the bound Ts · max ρ(L) / 2 · |w_0|
    is the one of the at-rest test, with ρ(L) the largest eigenvalue modulus of L met along
    the trajectory, and halving Ts must halve the difference.
    """
    rng = make_rng(6)
    gain, h, T = 5.0, 1e-4, 6.0
    Y = Y_CHEN
    d = rng.uniform(-3.0, 3.0, size=N_JOINTS)
    centre = np.array([0.3, 1.35, 1.1])  # folded arm: the slowest mode of L is fastest here
    amp, omega = 0.3, 2.0 * np.pi * 0.5
    kp, kd = np.array([400.0, 300.0, 200.0]), np.array([40.0, 30.0, 20.0])

    def f(y, tau):
        q, dq, w = y[:3], y[3:6], y[6:]
        ddq = robot.forward_dynamics(q, dq, tau + d)
        wdot = -gain * Y @ np.linalg.solve(robot.mass_matrix(q), w)
        return np.concatenate([dq, ddq, wdot])

    y = np.concatenate([centre, np.zeros(3), d])  # w(0) = d since d̂(0) = 0
    periods = {1e-3: 10, 5e-4: 5}  # observer period -> plant steps per period
    observers = {Ts: make_observer(Ts=Ts, gain=gain) for Ts in periods}
    for obs in observers.values():
        obs.reset(y[:3], y[3:6])
    gap = dict.fromkeys(periods, 0.0)
    rho, speed, masses = 0.0, 0.0, []
    tau = np.zeros(3)
    n_steps = round(T / h)
    for s in range(n_steps + 1):
        q, dq, w = y[:3], y[3:6], y[6:]
        if s > 0:
            for Ts, every in periods.items():
                if s % every == 0:
                    M = robot.mass_matrix(q)
                    nle = robot.nonlinear_effects(q, dq)
                    est = observers[Ts].update(M, nle, q, dq, tau, NO_V)
                    gap[Ts] = max(gap[Ts], np.linalg.norm((d - est) - w))
        if s % 10 == 0:  # new torque every 1 ms, from the sampled state
            M = robot.mass_matrix(q)
            masses.append(M)
            rho = max(rho, np.abs(np.linalg.eigvals(own_gain(gain, Y, M))).max())
            speed = max(speed, np.abs(dq).max())
            t = s * h
            q_ref = centre + amp * np.sin(omega * t)
            dq_ref = amp * omega * np.cos(omega * t)
            tau = robot.gravity_torque(q) + kp * (q_ref - q) + kd * (dq_ref - dq)
        if s < n_steps:
            y = rk4_step(f, y, h, tau)
    w_end = y[6:]
    w_obs_end = d - observers[1e-3].estimate
    norm0 = np.linalg.norm(d)
    # the arm really moved and its inertia really changed
    assert speed > 0.5
    assert np.abs(np.array(masses) - masses[0]).max() > 0.1 * np.abs(masses[0]).max()
    # the observer follows Eq (18) along the trajectory, at first order in Ts
    for Ts in periods:
        assert gap[Ts] < Ts * rho / 2.0 * norm0
    assert 1.8 < gap[1e-3] / gap[5e-4] < 2.2
    # and the error has decayed by more than a factor 100, as Eq (18) predicts
    assert np.linalg.norm(w_end) < norm0 / 100.0
    assert np.linalg.norm(w_obs_end) < norm0 / 100.0


# ---------------------------------------------------------- implicit vs explicit
def test_implicit_is_stable_where_explicit_diverges(robot, make_rng, make_observer):
    """Ts = 0.01, c = 20 at the pose maximising λ_max(Y M⁻¹): explicit grows, implicit decays.

    Forward Euler multiplies each mode by 1 - Ts c λ, so it diverges once Ts c λ_max > 2;
    backward Euler multiplies it by 1 / (1 + Ts c λ) < 1. The slowest mode has
    λ_min(Y M⁻¹) ≈ 0.08 at that pose (and below 0.36 everywhere in the workspace), so
    backward Euler needs (1 + 0.2 λ_min)^{-k} < 1e-3, i.e. about 420 steps, not 100, to
    reduce the error 1000-fold; 600 are taken. M does not depend on q1, so the search
    is over (q2, q3) only.
    """
    Ts, gain = 0.01, 20.0
    grid = [
        np.array([0.4, q2, q3])
        for q2 in np.linspace(-Q_LIMIT[1], Q_LIMIT[1], 13)
        for q3 in np.linspace(-Q_LIMIT[2], Q_LIMIT[2], 13)
    ]
    lam_max = [
        np.linalg.eigvals(Y_CHEN @ np.linalg.inv(robot.mass_matrix(q))).real.max() for q in grid
    ]
    q = grid[int(np.argmax(lam_max))]
    lam = np.linalg.eigvals(own_gain(gain, Y_CHEN, robot.mass_matrix(q)))
    assert np.all(np.abs(lam.imag) < 1e-9)
    assert Ts * lam.real.max() > 2.0 + 0.1  # forward Euler is unstable at this pose
    assert np.abs(1.0 - Ts * lam.real).max() ** 100 > 1e4
    d = make_rng(7).uniform(-5.0, 5.0, size=N_JOINTS)
    norm0 = np.linalg.norm(d)

    w_explicit = observe_at_rest(
        robot, make_observer(Ts=Ts, gain=gain, discretization="explicit"), q, d, 100
    )
    assert np.linalg.norm(w_explicit[-1]) > 1e3 * norm0

    w_implicit = observe_at_rest(robot, make_observer(Ts=Ts, gain=gain), q, d, 600)
    norms = np.linalg.norm(w_implicit, axis=1)
    assert norms[100] < norm0
    assert norms[-1] < 1e-3 * norm0
    assert np.all(norms < 1.5 * norm0)  # no transient blow-up on the way


# ---------------------------------------------------------------------- reset
@pytest.mark.parametrize("kind", KINDS)
def test_reset_starts_from_zero_estimate(robot, make_rng, make_observer, kind):
    """reset(q0, q̇0) gives d̂ = 0 with q̇0 ≠ 0, and the next sample stays consistent with d = 0.

    Without disturbance the first estimate after one 1 ms plant step must be O(Ts) small;
    a reset that left z = 0 instead of -p(q̇0) would give d̂ ≈ c Y q̇0 (tens of N·m here).
    """
    rng = make_rng(8)
    Ts, gain = 1e-3, 20.0
    obs = make_observer(Ts=Ts, gain=gain, kind=kind)
    # dirty the observer first, so reset has something to undo (nle, dq, tau drawn in
    # that order; q is not used by the NDO)
    nle_dirty, dq_dirty, tau_dirty = (rng.normal(size=3) for _ in range(3))
    obs.update(np.eye(3), nle_dirty, np.zeros(3), dq_dirty, tau_dirty, NO_V)
    assert np.abs(obs.estimate).max() > 0
    q0 = rng.uniform(-Q_LIMIT, Q_LIMIT)
    dq0 = rng.uniform(1.0, 2.0, size=3) * rng.choice([-1.0, 1.0], size=3)
    obs.reset(q0, dq0)
    np.testing.assert_array_equal(obs.estimate, np.zeros(3))
    np.testing.assert_allclose(obs.z + gain * Y_OF[kind] @ dq0, 0.0, atol=1e-12)
    # one held-torque plant step without disturbance, RK4 at 0.1 ms
    tau = robot.gravity_torque(q0) + rng.normal(0.0, 2.0, size=3)

    def f(y):
        return np.concatenate([y[3:], robot.forward_dynamics(y[:3], y[3:], tau)])

    y = np.concatenate([q0, dq0])
    for _ in range(10):
        y = rk4_step(f, y, 1e-4)
    q1, dq1 = y[:3], y[3:]
    est = obs.update(robot.mass_matrix(q1), robot.nonlinear_effects(q1, dq1), q1, dq1, tau, NO_V)
    assert np.linalg.norm(est) < 1e-2 * np.linalg.norm(gain * Y_OF[kind] @ dq0)


# --------------------------------------------------- spatial arm: Panda, 7 joints
@pytest.fixture(scope="module")
def panda():
    from hmpc_pin import load_robot

    fingers = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
    return load_robot("panda", gravity=9.81, locked_joints=fingers)


def panda_pose(panda, rng):
    return rng.uniform(panda.lower, panda.upper)


@pytest.mark.parametrize("seed", range(3))
def test_general_ndo_converges_at_rest_on_panda(panda, make_rng, seed):
    """Held still with τ = G − d, the implicit general NDO's error is exactly
    w_k = (I + Ts·c·M⁻¹)⁻ᵏ w_0 (computed here independently) and falls below 1e-8·|d|."""
    from hmpc_pin.compensation.observers import DisturbanceObserver

    rng = make_rng(seed)
    q, dq = panda_pose(panda, rng), np.zeros(7)
    d = rng.normal(0.0, 2.0, 7)
    tau = panda.gravity_torque(q) - d
    M, nle = panda.mass_matrix(q), panda.nonlinear_effects(q, dq)
    Ts, c = 0.01, 100.0
    obs = DisturbanceObserver(7, Ts, c, "general")
    obs.reset(q, dq)
    step = np.linalg.inv(np.eye(7) + Ts * c * np.linalg.inv(M))
    w_own = d.copy()
    for _ in range(300):
        w_own = step @ w_own
        w = d - obs.update(M, nle, q, dq, tau, np.zeros(7))
        np.testing.assert_allclose(w, w_own, atol=1e-9 * np.abs(d).max())
    assert np.abs(w).max() < 1e-8 * np.abs(d).max()


@pytest.mark.parametrize("seed", range(3))
def test_momentum_observer_rate_per_joint_on_panda(panda, make_rng, seed):
    """At rest, each joint's momentum residual error decays by exactly 1/(1 + Ts·K_i)."""
    from hmpc_pin.compensation.observers import MomentumObserver

    rng = make_rng(10 + seed)
    q, dq = panda_pose(panda, rng), np.zeros(7)
    d = rng.normal(0.0, 2.0, 7)
    tau = panda.gravity_torque(q) - d
    M, nle = panda.mass_matrix(q), panda.nonlinear_effects(q, dq)
    Ts = 0.01
    K = np.array([5.0, 10.0, 20.0, 40.0, 60.0, 80.0, 100.0])  # one gain per joint
    obs = MomentumObserver(panda, Ts, K)
    obs.reset(q, dq)
    for k in range(1, 60):
        w = d - obs.update(M, nle, q, dq, tau, np.zeros(7))
        np.testing.assert_allclose(w, d / (1.0 + Ts * K) ** k, atol=1e-10)


@pytest.mark.parametrize("kind", ["general", "momentum"])
def test_spatial_observers_converge_on_moving_panda(panda, make_rng, kind):
    """The Panda moves (PD to a moving target, RK4 plant at 1 ms with ABA, constant
    disturbance d); the observer at Ts = 10 ms, fed with τ held over each period,
    estimates d to 5 % after 2 s at random start poses. The residual error is the
    observers' O(Ts) discretisation of the moving arm's dynamics (they see the mean
    acceleration of the period, evaluated with M and C at its end), not a lag on d."""
    from hmpc_pin.compensation.observers import DisturbanceObserver, MomentumObserver

    rng = make_rng(20)
    Ts, h = 0.01, 0.001
    for _ in range(2):
        q = panda_pose(panda, rng) * 0.8
        q_home, dq = q.copy(), np.zeros(7)
        d = rng.normal(0.0, 1.0, 7) * np.diag(panda.mass_matrix(q))
        if kind == "momentum":
            obs = MomentumObserver(panda, Ts, 50.0)
        else:
            obs = DisturbanceObserver(7, Ts, 50.0, kind, "implicit")
        obs.reset(q, dq)
        tau_prev = v_prev = None
        for k in range(200):
            t = k * Ts
            M, nle = panda.mass_matrix(q), panda.nonlinear_effects(q, dq)
            if tau_prev is not None:
                est = obs.update(M, nle, q, dq, tau_prev, v_prev)
            target = q_home + 0.2 * np.sin(2 * np.pi * 0.2 * t)
            v = 100.0 * (target - q) - 20.0 * dq
            tau = nle + M @ v
            for _ in range(round(Ts / h)):
                q, dq = rk4_step_state(panda, q, dq, tau + d, h)
            tau_prev, v_prev = tau, v
        assert np.abs(dq).max() > 0.05  # it really moved
        np.testing.assert_allclose(est, d, atol=5e-2 * np.abs(d).max())


def rk4_step_state(robot, q, dq, tau, h):
    def f(y):
        return np.concatenate([y[7:], robot.forward_dynamics(y[:7], y[7:], tau)])

    y = rk4_step(f, np.concatenate([q, dq]), h)
    return y[:7], y[7:]


def test_general_gain_bound_matches_finite_difference_mdot(panda, make_rng):
    """½‖Ṁ‖₂ of :func:`general_gain_bound` equals the bound recomputed from finite
    differences of M along the same sampled velocities."""
    from hmpc_pin.compensation.observers import general_gain_bound

    bound = general_gain_bound(panda, samples=30, seed=4)
    rng = np.random.default_rng(4)
    lo, hi = np.clip(panda.lower, -np.pi, np.pi), np.clip(panda.upper, -np.pi, np.pi)
    worst, eps = 0.0, 1e-6
    for _ in range(30):
        q = rng.uniform(lo, hi)
        sign = rng.choice([-1.0, 1.0], size=7)
        for dq in (sign * panda.velocity_limit, -sign * panda.velocity_limit):
            Md = (panda.mass_matrix(q + eps * dq) - panda.mass_matrix(q - eps * dq)) / (2 * eps)
            worst = max(worst, 0.5 * np.linalg.norm(Md, 2))
    assert bound == pytest.approx(worst, rel=1e-5)
    assert 0 < bound < 100.0  # the configs' gain c = 100 is above it


# ------------------------------------------- the compiled NDO against its numpy oracle
EPS = np.finfo(float).eps


def _oracle_tolerance(M, cY, Ts, *scales) -> float:
    """Rounding bound of one update: both sides solve an n×n system, the compiled one
    (M + Ts cY) by Eigen's LU, the oracle (I + Ts cY M⁻¹) by LAPACK after forming M⁻¹; each
    is accurate to about κ·n·ε relative, κ the condition number of the worse of the two,
    times the largest magnitude in play [N·m]. A factor 10 covers the few updates an error
    survives before the (contracting) observer forgets it."""
    n = M.shape[0]
    kappa = max(np.linalg.cond(M), np.linalg.cond(M + Ts * cY))
    return 10.0 * kappa * n * EPS * max(1.0, *(float(np.max(np.abs(s))) for s in scales))


@pytest.mark.parametrize("arm", ["planar3", "panda"])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("discretization", ["implicit", "explicit"])
def test_compiled_ndo_equals_numpy_oracle_on_random_states(
    robot, panda, make_rng, arm, kind, discretization
):
    """40 updates at random states (q in the joint range, q̇, τ random): the compiled
    observer's z and d̂ equal the oracle's (tests/reference/observers.py) to rounding."""
    from hmpc_pin.compensation.observers import observer_matrix

    from .reference.observers import NumpyNDO

    model = robot if arm == "planar3" else panda
    n, Ts = model.nq, 1e-3
    # explicit Euler is stable only for Ts·c·λmax(Y M⁻¹) < 2: a gain well inside for both
    gain = 5.0 if discretization == "implicit" else 0.2
    rng = make_rng(11)
    obs = DisturbanceObserver(n, Ts, gain, kind=kind, discretization=discretization)
    oracle = NumpyNDO(gain * observer_matrix(kind, n), Ts, discretization == "implicit")
    lo, hi = np.clip(model.lower, -np.pi, np.pi), np.clip(model.upper, -np.pi, np.pi)
    dq0 = rng.normal(size=n)
    obs.reset(np.zeros(n), dq0)
    oracle.reset(dq0)
    # z₀ = −cY q̇₀: a matrix-vector product, summed in another order on each side
    bound = n * EPS * float(np.max(np.abs(oracle.cY) @ np.abs(dq0)))
    assert np.max(np.abs(obs.z - oracle.z)) <= bound
    for _ in range(40):
        q, dq = rng.uniform(lo, hi), rng.normal(size=n)
        tau = rng.normal(size=n) * 10.0
        M, nle = model.mass_matrix(q), model.nonlinear_effects(q, dq)
        got = obs.update(M, nle, q, dq, tau)
        want = oracle.update(M, nle, dq, tau)
        tol = _oracle_tolerance(M, oracle.cY, Ts, want, nle, tau, oracle.z)
        assert np.max(np.abs(got - want)) <= tol
        assert np.max(np.abs(obs.z - oracle.z)) <= tol
        assert np.array_equal(got, obs.estimate)


def test_compiled_step_estimate_equals_numpy_oracle_along_a_closed_loop():
    """The paper's combined run (1 s, the compiled step advancing the NDO inside C++): the
    recorded states and applied torques, with M and C q̇ + G from Pinocchio's Python API,
    replayed into the oracle give the recorded estimate d̂ at every step, to rounding."""
    from dataclasses import replace

    import hmpc_pin

    from .reference.observers import NumpyNDO

    config = hmpc_pin.load_config("paper_combined")
    config = replace(config, simulation=replace(config.simulation, duration=1.0))
    ex = hmpc_pin.Experiment.from_config(config)
    obs = ex.controller.compensation
    assert isinstance(obs, DisturbanceObserver) and ex.controller.fused
    result = ex.run()
    assert result.complete and len(result.t) >= 100
    robot = ex.robot
    oracle = NumpyNDO(obs.cY, obs.Ts, obs.discretization == "implicit")
    oracle.reset(result.dq[0])
    worst = 0.0
    for k in range(1, len(result.t)):
        q, dq = result.q[k], result.dq[k]
        M, nle = robot.mass_matrix(q), robot.nonlinear_effects(q, dq)
        want = oracle.update(M, nle, dq, result.tau_applied[k - 1])
        tol = _oracle_tolerance(M, oracle.cY, obs.Ts, want, nle, result.tau_applied[k - 1],
                                oracle.z)  # fmt: skip
        worst = max(worst, float(np.max(np.abs(result.d_hat[k] - want))) / tol)
    assert worst <= 1.0


def test_ndo_state_survives_pickling(make_observer, make_rng):
    """A pickled observer (sweep workers) carries z and d̂ and keeps advancing the same."""
    import pickle

    rng = make_rng(3)
    obs = make_observer(gain=5.0)
    obs.reset(np.zeros(3), rng.normal(size=3))
    M = np.diag([2.0, 1.5, 1.0])
    args = (M, rng.normal(size=3), np.zeros(3), rng.normal(size=3), rng.normal(size=3))
    obs.update(*args)
    twin = pickle.loads(pickle.dumps(obs))
    np.testing.assert_array_equal(twin.z, obs.z)
    np.testing.assert_array_equal(twin.update(*args), obs.update(*args))
