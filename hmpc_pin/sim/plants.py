"""Plants: the arm the controller drives, advanced one control period at a time.

The :class:`Plant` protocol is what :func:`~hmpc_pin.sim.simulate.simulate` (and a
real-time loop) needs: ``reset`` to a state, ``advance`` over one control period with
the torque held, and the disturbance at the current state for the record.
Implementations here integrate Pinocchio's ABA: :class:`RK4Plant` (classical
Runge–Kutta, the default) and :class:`EulerPlant` (semi-implicit Euler), both with the
disturbance evaluated at every internal step. Plant classes are found by name in
:data:`PLANTS` (``[plant] integrator``).

:class:`RK4Plant` advances :math:`M\\ddot q + C\\dot q + G = \\tau + d(t, q, \\dot q)`
(Eq 1) over one control period :math:`T_s` with the torque held, by classical
Runge–Kutta (RK4) steps of ``dt``, the disturbance evaluated at every stage:

.. math::

    k_1 = f(t_s, x), \\quad k_2 = f(t_s + h/2, x + \\tfrac h2 k_1), \\quad
    k_3 = f(t_s + h/2, x + \\tfrac h2 k_2), \\quad k_4 = f(t_s + h, x + h k_3),

    x \\leftarrow x + \\tfrac h6 (k_1 + 2k_2 + 2k_3 + k_4), \\qquad
    f(t, [q; \\dot q]) = [\\dot q;\\ \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q))].

This is the simulation's hot loop (40 ABA calls per 10 ms control period at 1 ms),
written for few Python-level numpy calls, not for a different result:

* One buffer row per stage, ``[q_j | q̇_j | q̈_j | 1]``, so that the stage state
  :math:`[q_j; \\dot q_j]` and the stage derivative :math:`k_j = [\\dot q_j; \\ddot q_j]`
  are contiguous views: each stage update is one multiply and one add, and the final
  combination one product with the weights ``h/6·(1, 2, 2, 1)``.
* Terms that say what they are are evaluated fused: time-only terms (a
  ``sample_times(times)`` method, e.g. :class:`~hmpc_pin.sim.disturbances.GaussianPulse`)
  at all 3·substeps stage times of
  the period in one call each, added to the held torque once per period; one
  Coulomb–viscous friction term (a ``friction_coefficients()`` method, e.g.
  :class:`~hmpc_pin.sim.disturbances.CoulombViscousFriction`)
  inside one product per stage: with :math:`\\mathrm{sgn}(\\dot q_j)` written where
  :math:`\\ddot q_j` goes next, the row ends in
  :math:`e_j = [\\dot q_j; \\mathrm{sgn}(\\dot q_j); 1]` and the ABA torque is
  :math:`e_j^T W_j`, :math:`W_j = [-\\mathrm{diag}(a); -\\mathrm{diag}(b);
  (\\tau + d_\\mathrm{pulse}(t_j))^T]`. Each fused term is checked once, at
  construction, against its own ``d(t, q, dq)`` at a few random points (a subclass
  that changed ``__call__`` only is not fused). Any other disturbance (a user callable,
  two friction terms) is called as ``d(t, q, dq)`` at every stage.
* numpy outputs passed positionally (cheaper than ``out=``), loops over precomputed
  views: six numpy calls and one ``pin.aba`` per stage.

The results equal the plain loop (``q2 = q + h/2·dq`` …, ``aba(q, dq, tau + d(t, q, dq))``
per stage) up to floating-point rounding (tested to 1e-12 on the paper scenario).

Native backend (``backend``, :mod:`hmpc_pin.native`): with fused terms only and no mimic
joint, the whole period -- the same stages, the same stage torques (time-only terms
tabulated here, friction :math:`-(a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q)` per stage) and
Pinocchio's ABA -- runs in one C++ call; it equals the Python loop up to rounding
(``tests/native``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..exceptions import ConfigError, DimensionError
from ..model.robot import Robot
from ..native import load as load_native
from ..native import model_string, resolve_backend
from .base import Plant
from .disturbances import ZeroDisturbance

__all__ = ["PLANTS", "EulerPlant", "Plant", "RK4Plant", "split_disturbance"]

FloatArray = NDArray[np.float64]

#: Periods whose time-only terms :class:`RK4Plant` tabulates in one call per term.
PULSE_CHUNK = 64


def _substeps(Ts: float, dt: float) -> int:
    substeps = round(Ts / dt)
    if substeps < 1 or abs(substeps * dt - Ts) > 1e-9 * Ts:
        raise ConfigError(
            "plant.dt",
            f"dt={dt:g} does not divide the period Ts={Ts:g} the plant advances by (the "
            "control period; for `realtime`, the interface period 1/rate); "
            "expected Ts / dt to be a whole number >= 1",
        )
    return substeps


def _agrees(term, fused, n: int) -> bool:
    """Whether a term's fused form equals its own ``d(t, q, dq)`` at a few random points."""
    rng = np.random.default_rng(0)
    for _ in range(3):
        t = float(rng.uniform(0.0, 10.0))
        q, dq = rng.standard_normal(n), rng.standard_normal(n)
        try:
            direct = np.broadcast_to(np.asarray(term(t, q, dq), dtype=float), (n,))
            other = np.broadcast_to(np.asarray(fused(t, q, dq), dtype=float), (n,))
        except (ValueError, TypeError):
            return False
        if not np.allclose(direct, other, rtol=1e-12, atol=1e-12):
            return False
    return True


def split_disturbance(disturbance, n: int):
    """Split ``disturbance`` into fused parts, or return ``None`` if it has other terms.

    Returns:
        ``(pulses, friction)``: the time-only terms (with ``sample_times``) and the
        single Coulomb–viscous term (with ``friction_coefficients``, or ``None``);
        ``None`` instead of the pair when the disturbance has any other term (a user
        callable, two friction terms), which is then evaluated term by term.
    """
    terms = getattr(disturbance, "terms", (disturbance,))
    pulses, friction = [], []
    for term in terms:
        times_fn = getattr(term, "sample_times", None)
        coef_fn = getattr(term, "friction_coefficients", None)
        if callable(times_fn) and _agrees(
            term, lambda t, q, dq, f=times_fn: f(np.array([t]))[0], n
        ):
            pulses.append(term)
        elif callable(coef_fn):
            a, b = (np.asarray(c, dtype=float) for c in coef_fn())
            if a.shape not in ((), (n,)) or b.shape not in ((), (n,)):
                return None  # let the plain evaluation raise its own broadcasting error
            if not _agrees(term, lambda t, q, dq, a=a, b=b: -(a * dq + b * np.sign(dq)), n):
                return None
            friction.append((a, b))
        else:
            return None
    if len(friction) > 1:
        return None
    return pulses, (friction[0] if friction else None)


class RK4Plant:
    """Classical RK4 integration of a Pinocchio model over one control period.

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot` (its own ``model``/``data``).
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for none.
        Ts: Control period [s] (the torque is held over it).
        dt: Integration step [s]; must divide ``Ts`` (default 1 ms).
        backend: ``"auto"`` (the native period when it loads and the disturbance is made
            of fused terms only, with no mimic joint), ``"native"`` (an error otherwise)
            or ``"python"`` (:func:`hmpc_pin.native.resolve_backend`).

    Attributes:
        native: Whether the period runs natively.
    """

    name = "rk4"

    def __init__(
        self,
        robot: Robot,
        disturbance=None,
        Ts: float = 0.01,
        dt: float = 0.001,
        backend: str = "auto",
    ):
        n = robot.nq
        substeps = _substeps(Ts, dt)
        self.nq = self.n = n
        self.robot = robot
        self.Ts = float(Ts)
        self.model, self.data = robot.model, robot.data
        disturbance = disturbance if disturbance is not None else ZeroDisturbance(n)
        self.disturbance = disturbance
        self.h = h = Ts / substeps
        self.substeps = substeps
        self.t0, self.k, self.t = 0.0, 0, 0.0
        self.q, self.dq = np.zeros(n), np.zeros(n)
        self._chunk_k, self._chunk = 0, np.empty((0, 3 * substeps, n))
        self._split = split_disturbance(disturbance, n)
        # Stage rows [q_j | dq_j | ddq_j | 1]; row 0 holds the current state.
        self._B = B = np.zeros((4, 3 * n + 1))
        B[:, 3 * n] = 1.0
        self._x = B[0, : 2 * n]
        self._K = B[:, n : 3 * n]  # k_j = [dq_j | ddq_j], shape (4, 2n)
        self._rows = [
            (B[j, :n], B[j, n : 2 * n], B[j, 2 * n : 3 * n], B[j, n : 3 * n], B[j, n:])
            for j in range(4)
        ]
        self._next = [B[j, : 2 * n] for j in range(1, 4)]
        self._c = [np.full(2 * n, c) for c in (0.5 * h, 0.5 * h, h)]
        self._w = (h / 6.0) * np.array([1.0, 2.0, 2.0, 1.0])
        self._tmp = np.empty(2 * n)
        self._dx = np.empty(2 * n)
        self._u = np.empty(n)
        # The stage times of a period, t_s = t + s·h, t_s + h/2 and t_s + h for each step s,
        # as three blocks of one flat array (what the plain loop computes, the same way).
        S = substeps
        self._s_h = np.arange(S) * h
        self._half = 0.5 * h
        self._times = np.empty(3 * S)
        self._t0, self._tm, self._t1 = self._times[:S], self._times[S : 2 * S], self._times[2 * S :]
        # Per stage time (rows ordered as _times) the matrix W with [dq | sgn(dq) | 1] @ W =
        # tau + pulses(t) - (a·dq + b·sgn(dq)): rows -diag(a), -diag(b), and T = tau +
        # pulses(t), the held torque plus the time-only terms at that stage time.
        self._W = W = np.zeros((3 * S, 2 * n + 1, n))
        self._T = W[:, 2 * n, :]
        self._W_triples = [(W[s], W[S + s], W[2 * S + s]) for s in range(S)]
        self._T_triples = [(self._T[s], self._T[S + s], self._T[2 * S + s]) for s in range(S)]
        if self._split is not None:
            pulses, friction = self._split
            self._friction = friction
            # Each pulse's coefficients tiled over the 3·S stage times: the pulses of a
            # whole period in a few flat numpy calls.
            self._pulses = pulses
            if friction is not None:
                W[:, :n, :] = -np.diag(np.broadcast_to(friction[0], (n,)))
                W[:, n : 2 * n, :] = -np.diag(np.broadcast_to(friction[1], (n,)))
        unsupported = None
        if self._split is None:
            unsupported = ("a disturbance with terms other than time-only ones and one "
                           "Coulomb-viscous friction (it is called in Python at every stage)")
        elif robot.mimic_joints:
            unsupported = "mimic joints (Pinocchio has no ABA for them)"
        self.native = resolve_backend(backend, "plant.backend", unsupported)
        if self.native:
            self._kernel = load_native().RK4(model_string(robot))
            self._Tn = np.empty((3 * S, n))  # stage torques, C-contiguous
            zero = np.zeros(n)
            a, b = self._friction if self._friction is not None else (zero, zero)
            self._ab = (np.broadcast_to(a, (n,)).astype(float),
                        np.broadcast_to(b, (n,)).astype(float))  # fmt: skip

    def __getstate__(self) -> dict:
        """Picklable: the native kernel is rebuilt from the robot on unpickling."""
        state = self.__dict__.copy()
        state.pop("_kernel", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.native:
            self._kernel = load_native().RK4(model_string(self.robot))

    def _stage_times(self, t: float) -> np.ndarray:
        """Stage times of the period starting at ``t``: blocks t_s, t_s + h/2, t_s + h."""
        t0 = self._t0
        np.add(t, self._s_h, t0)
        np.add(t0, self._half, self._tm)
        np.add(t0, self.h, self._t1)
        return self._times

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s]."""
        self.q = np.array(q0, dtype=float)
        self.dq = np.array(dq0, dtype=float)
        if self.q.shape != (self.n,) or self.dq.shape != (self.n,):
            raise DimensionError(
                f"plant state of shapes {self.q.shape}, {self.dq.shape}; expected ({self.n},)"
            )
        self.t0, self.k, self.t = float(t0), 0, float(t0)
        self._chunk_k, self._chunk = 0, np.empty((0, 3 * self.substeps, self.n))

    def disturbance_now(self) -> FloatArray:
        """:math:`d(t, q, \\dot q)` [N·m] at the current time and state."""
        if not self.native:
            return self.disturbance(self.t, self.q, self.dq)
        # The fused terms: the time-only ones from the table (stage 0 of the period is t
        # itself), the friction here (the same terms as d(t, q, dq), summed in another order).
        dq = self.dq
        d = self._pulses_at(self.k)[0].copy() if self._pulses else np.zeros(self.n)
        if self._friction is not None:
            a, b = self._ab
            d -= a * dq + b * np.sign(dq)
        return d

    def _pulses_at(self, k: int) -> np.ndarray:
        """The time-only terms at the stage times of period ``k`` (rows as ``_times``),
        tabulated :data:`PULSE_CHUNK` periods per call of each term: the same stage times,
        computed the same way as :meth:`_stage_times` (``t = t0 + Ts·k``), so the same values."""
        j = k - self._chunk_k
        chunk = self._chunk
        if 0 <= j < chunk.shape[0]:
            return chunk[j]
        t = self.t0 + self.Ts * np.arange(k, k + PULSE_CHUNK)
        t_s = np.add.outer(t, self._s_h)
        times = np.concatenate([t_s, t_s + self._half, t_s + self.h], axis=1).ravel()
        total = self._pulses[0].sample_times(times)
        for term in self._pulses[1:]:
            total = total + term.sample_times(times)
        self._chunk_k, self._chunk = k, total.reshape(PULSE_CHUNK, 3 * self.substeps, self.n)
        return self._chunk[0]

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Integrate over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``."""
        n = self.n
        x = self._x
        x[:n] = self.q
        x[n:] = self.dq
        if self.native:
            self._advance_native(tau)
        elif self._split is None:
            self._advance_generic(self._stage_times(self.t), tau)
        else:
            self._advance_fused(tau)
        self.k += 1
        self.t = self.t0 + self.Ts * self.k
        self.q, self.dq = x[:n].copy(), x[n:].copy()
        return self.q, self.dq

    def _advance_native(self, tau: np.ndarray) -> None:
        """The period in one native call (:mod:`hmpc_pin.native`), the same stages."""
        T = self._Tn
        if self._pulses:
            np.add(tau, self._pulses_at(self.k), T)
        else:
            T[:] = tau
        n, x = self.n, self._x
        a, b = self._ab
        self._kernel.period(x[:n], x[n:], T, a, b, self._friction is not None, self.h)

    def _advance_fused(self, tau: np.ndarray) -> None:
        """RK4 with the time-only terms tabulated and the friction fused (module doc)."""
        if self._pulses:
            # Time-only terms at all stage times of the period (tabulated per chunk).
            np.add(tau, self._pulses_at(self.k), self._T)
        else:
            self._T[:] = tau
        model, data, aba = self.model, self.data, self.robot.aba
        rows = self._rows
        (q0, v0, a0, k0, e0), (q1, v1, a1, k1, e1) = rows[0], rows[1]
        (q2, v2, a2, k2, e2), (q3, v3, a3, _, e3) = rows[2], rows[3]
        x1, x2, x3 = self._next
        c1, c2, c3 = self._c
        x, K, w, tmp, dx = self._x, self._K, self._w, self._tmp, self._dx
        add, mul, sign, dot = np.add, np.multiply, np.sign, np.dot
        # (outputs passed positionally: a little cheaper than out=, 40 times per period)
        if self._friction is None:
            for r0, r1, r2 in self._T_triples:
                a0[:] = aba(model, data, q0, v0, r0)
                mul(k0, c1, tmp)
                add(x, tmp, x1)
                a1[:] = aba(model, data, q1, v1, r1)
                mul(k1, c2, tmp)
                add(x, tmp, x2)
                a2[:] = aba(model, data, q2, v2, r1)
                mul(k2, c3, tmp)
                add(x, tmp, x3)
                a3[:] = aba(model, data, q3, v3, r2)
                dot(w, K, dx)
                add(x, dx, x)
            return
        for W0, W1, W2 in self._W_triples:
            # sgn(dq_j) is written where ddq_j goes next, so that the stage row ends in
            # e_j = [dq_j | sgn(dq_j) | 1] and the torque is one product e_j @ W.
            sign(v0, a0)
            a0[:] = aba(model, data, q0, v0, e0.dot(W0))
            mul(k0, c1, tmp)
            add(x, tmp, x1)
            sign(v1, a1)
            a1[:] = aba(model, data, q1, v1, e1.dot(W1))
            mul(k1, c2, tmp)
            add(x, tmp, x2)
            sign(v2, a2)
            a2[:] = aba(model, data, q2, v2, e2.dot(W1))
            mul(k2, c3, tmp)
            add(x, tmp, x3)
            sign(v3, a3)
            a3[:] = aba(model, data, q3, v3, e3.dot(W2))
            dot(w, K, dx)
            add(x, dx, x)

    def _advance_generic(self, times: np.ndarray, tau: np.ndarray) -> None:
        """RK4 calling ``d(t, q, dq)`` at every stage (with copies of the stage state)."""
        dist = self.disturbance
        model, data, aba = self.model, self.data, self.robot.aba
        rows = self._rows
        nxt = self._next
        c = self._c
        x, K, w, tmp, dx, u = self._x, self._K, self._w, self._tmp, self._dx, self._u
        stage_times = zip(self._t0.tolist(), self._tm.tolist(), self._t1.tolist(), strict=True)
        for t0, tm, t1 in stage_times:
            for j, ts in enumerate((t0, tm, tm, t1)):
                qj, vj, aj, kj, _ = rows[j]
                np.add(tau, dist(ts, qj.copy(), vj.copy()), out=u)
                aj[:] = aba(model, data, qj, vj, u)
                if j < 3:
                    np.multiply(kj, c[j], out=tmp)
                    np.add(x, tmp, out=nxt[j])
            np.dot(w, K, out=dx)
            np.add(x, dx, out=x)


class EulerPlant:
    """Semi-implicit Euler integration of a Pinocchio model over one control period.

    Per step of ``h = dt``: :math:`\\dot q \\leftarrow \\dot q + h\\,\\mathrm{ABA}(q, \\dot q,
    \\tau + d(t, q, \\dot q))`, then :math:`q \\leftarrow q + h\\dot q`.

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot`.
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for none.
        Ts: Control period [s].
        dt: Integration step [s]; must divide ``Ts``.
    """

    name = "euler"
    native = False

    def __init__(self, robot: Robot, disturbance=None, Ts: float = 0.01, dt: float = 0.001):
        self.nq = self.n = robot.nq
        self.robot = robot
        self.Ts = float(Ts)
        self.substeps = _substeps(Ts, dt)
        self.h = self.Ts / self.substeps
        self.model, self.data = robot.model, robot.data
        self.disturbance = disturbance if disturbance is not None else ZeroDisturbance(self.n)
        self.t0, self.k, self.t = 0.0, 0, 0.0
        self.q, self.dq = np.zeros(self.n), np.zeros(self.n)

    reset = RK4Plant.reset
    disturbance_now = RK4Plant.disturbance_now

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Integrate over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``."""
        q, dq, t, h = self.q, self.dq, self.t, self.h
        model, data, aba, dist = self.model, self.data, self.robot.aba, self.disturbance
        for s in range(self.substeps):
            dq = dq + h * aba(model, data, q, dq, tau + dist(t + s * h, q, dq))
            q = q + h * dq
        self.k += 1
        self.t = self.t0 + self.Ts * self.k
        self.q, self.dq = q, dq
        return q, dq


#: Plant classes by ``[plant] integrator`` name (and ``"mujoco"``: the MuJoCo plant,
#: registered by :mod:`.mujoco`, chosen by ``[plant] engine``; it needs the ``mujoco`` extra).
PLANTS: dict[str, type] = {cls.name: cls for cls in (RK4Plant, EulerPlant)}
