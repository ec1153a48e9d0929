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
    f(t, [q; \\dot q]) = [\\dot q;\\ \\mathrm{ABA}(q, \\dot q, \\tau + d(t, q, \\dot q)
        - B\\dot q - F\\,\\mathrm{sgn}\\,\\dot q)].

:math:`B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q` is the arm's own joint damping and Coulomb
friction, the URDF's ``<dynamics damping friction>``
(:attr:`~hmpc_pin.model.robot.Robot.joint_damping`, ``joint_friction``), applied by both
plants here unless ``joint_dynamics=False``.

The Coulomb term is discontinuous at :math:`\\dot q_i = 0`, where RK4 with
:math:`\\mathrm{sgn}` per stage converges at first order only. :class:`RK4Plant` (``coulomb =
"stick-slip"``, the default) integrates it as a stick-slip law with event location: the sign
of each joint's Coulomb term (the URDF's :math:`F` and the compiled ``[disturbance.friction]``
term's :math:`b`) is held over a step at :math:`\\mathrm{sgn}\\,\\dot q_i` of its start, the
step is split where a velocity changes sign (the crossing found by regula falsi on the RK4
step's length, to :math:`10^{-13}` of the step), and a joint at rest sticks: its friction
takes the value :math:`\\phi_i \\in [-F_i, F_i]` that keeps :math:`\\ddot q_i = 0` (with the
other stuck joints, :math:`(M^{-1})_{SS}\\,\\phi_S = -(M^{-1}u)_S`) until that value would
leave the interval, where it breaks away (another event) and slides against it. An arm
with every joint at rest is held by the closed form :math:`\\phi = G(q) - u` (one RNEA at
:math:`\\dot q = 0` per position, checked at each step's start and end as the events are)
instead of that algebra at every stage. Between events the field is smooth and RK4 keeps
its fourth order (``tests/test_plant_step.py`` measures it against scipy's DOP853 with the
same events). ``coulomb = "sign"``:
:math:`\\mathrm{sgn}\\,\\dot q` with :math:`\\mathrm{sgn}\\,0 = 0` per stage, which chatters
about :math:`\\dot q = 0` rather than sticking (versions before 0.3; :class:`EulerPlant`
always). A disturbance evaluated as a function (a sum with a term of the user's) keeps its
own terms, but for its Coulomb–viscous terms (:func:`friction_in`), which follow the same
law as when compiled. MuJoCo's
``frictionloss`` is a soft constraint that holds a joint at rest while the torque is below
:math:`f`.

:func:`choose_step` picks the largest step dividing the period whose error against the half
step stays within a tolerance (``[plant] tolerance``).

The period is one call into the compiled core (``cpp/src/rk4.cpp``, ``RK4``), the only
implementation of it (its numpy oracle, the plain loop, is ``tests/reference/rk4.py``). The
disturbance is handed to the compiled plant as its Disturbance port
(:func:`~hmpc_pin.sim.disturbances.disturbance_port`), whose terms say what they are: when
each is of time alone (:class:`~hmpc_pin.sim.disturbances.TimeOnly`, e.g.
:class:`~hmpc_pin.sim.disturbances.GaussianPulse`, compiled) or one Coulomb–viscous friction
(:class:`~hmpc_pin.sim.disturbances.CoulombViscousFriction`, compiled:
:math:`-(a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q)`), the disturbance is compiled into the
period: the time-only terms evaluated at the 3·substeps stage times of a period at once and
added to the held torque, the friction evaluated per stage. Any other disturbance (a user
callable, two friction terms) is called at every stage as ``d(t, q, dq)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._deprecated import deprecated
from ..exceptions import ConfigError, DimensionError, SimulationError
from ..model.robot import Robot
from ..native import deprecated_backend, model_string, replaced
from ..native import load as load_native
from .base import Plant
from .disturbances import (
    CoulombViscousFriction,
    Disturbance,
    TimeOnly,
    ZeroDisturbance,
    disturbance_port,
)

__all__ = [
    "COULOMB_LAWS",
    "PLANTS",
    "EulerPlant",
    "Plant",
    "RK4Plant",
    "choose_step",
    "friction_in",
    "split_disturbance",
]

FloatArray = NDArray[np.float64]

#: How :class:`RK4Plant` integrates the Coulomb friction (``[plant] coulomb``; module
#: docstring): located sign changes and sticking, or the sign per stage.
COULOMB_LAWS = ("stick-slip", "sign")


def __getattr__(name: str):
    """``PULSE_CHUNK`` of earlier versions (:mod:`hmpc_pin._deprecated`), with a
    :class:`DeprecationWarning`."""
    return deprecated(__name__, name)


def substeps_per_period(Ts: float, dt: float) -> int:
    substeps = round(Ts / dt)
    if substeps < 1 or abs(substeps * dt - Ts) > 1e-9 * Ts:
        raise ConfigError(
            "plant.dt",
            f"dt={dt:g} does not divide the period Ts={Ts:g} the plant advances by (the "
            "control period; for `realtime`, the interface period 1/rate); "
            "expected Ts / dt to be a whole number >= 1",
        )
    return substeps


def _reset_state(plant, q0: FloatArray, dq0: FloatArray, t0: float) -> None:
    """A Pinocchio plant's state ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s], checked."""
    plant.q = np.array(q0, dtype=float)
    plant.dq = np.array(dq0, dtype=float)
    if plant.q.shape != (plant.n,) or plant.dq.shape != (plant.n,):
        raise DimensionError(
            f"plant state of shapes {plant.q.shape}, {plant.dq.shape}; expected ({plant.n},)"
        )
    plant.t0, plant.k, plant.t = float(t0), 0, float(t0)
    plant._was_reset = True


def held_torque(plant, tau) -> FloatArray:
    """``tau`` [N·m] as the (n,) float array a plant's ``advance`` holds, after checking
    that the plant was reset (its state and time are set by ``reset`` only).

    Raises:
        SimulationError: ``advance`` before ``reset``.
        DimensionError: ``tau`` is not one torque per joint.
    """
    if not plant._was_reset:
        raise SimulationError(
            f"{type(plant).__name__}.advance before reset: call reset(q0, dq0) first to "
            "set the state the period starts from"
        )
    tau = np.asarray(tau, dtype=float)
    if tau.shape != (plant.n,):
        raise DimensionError(
            f"{type(plant).__name__}.advance: torque of shape {tau.shape}; expected "
            f"({plant.n},), one per joint of the plant"
        )
    return tau


def _joint_terms(robot: Robot, on: bool) -> tuple[FloatArray, FloatArray] | None:
    """``(B, F)`` of ``robot`` (its URDF's joint damping and Coulomb friction) when ``on``
    and any is non-zero, else ``None``."""
    if not on:
        return None
    n = robot.nq
    b = np.asarray(getattr(robot, "joint_damping", np.zeros(n)), dtype=float).copy()
    f = np.asarray(getattr(robot, "joint_friction", np.zeros(n)), dtype=float).copy()
    return (b, f) if (b.any() or f.any()) else None


def _friction_of(term, n: int) -> tuple[FloatArray, FloatArray] | None:
    """``(a, b)`` (n,) of a Coulomb–viscous term
    (:class:`~hmpc_pin.sim.disturbances.CoulombViscousFriction`, whose value is
    :math:`-(a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q)` by definition), else ``None`` (also
    for coefficients of another shape: the term's own call then raises its error)."""
    if not isinstance(term, CoulombViscousFriction):
        return None
    a, b = (np.asarray(c, dtype=float) for c in term.friction_coefficients())
    if a.shape not in ((), (n,)) or b.shape not in ((), (n,)):
        return None
    return np.broadcast_to(a, (n,)).astype(float), np.broadcast_to(b, (n,)).astype(float)


def friction_in(disturbance, n: int) -> tuple[FloatArray, FloatArray] | None:
    """The summed ``(a, b)`` of the Coulomb–viscous terms of a disturbance evaluated as a
    function (a sum with other terms), which the stick-slip period then integrates as the
    compiled one (``RK4.set_friction_in_disturbance``); ``None`` without any."""
    terms = _terms(disturbance)
    found = [ab for ab in (_friction_of(term, n) for term in terms) if ab is not None]
    if not found:
        return None
    return (
        np.asarray(sum(a for a, _ in found), dtype=float),
        np.asarray(sum(b for _, b in found), dtype=float),
    )


def _terms(disturbance) -> tuple:
    """The summed terms of a :class:`~hmpc_pin.sim.disturbances.Disturbance` (``()`` for
    the zero one); any other callable is one term, whatever attributes it has (a user
    object's own ``terms`` is not the package's sum)."""
    return disturbance.terms if isinstance(disturbance, Disturbance) else (disturbance,)


def split_disturbance(disturbance, n: int):
    """Split ``disturbance`` into its compiled parts, or return ``None`` if it has other terms.

    Returns:
        ``(pulses, friction)``: the time-only terms
        (:class:`~hmpc_pin.sim.disturbances.TimeOnly`) and the single Coulomb–viscous
        term's ``(a, b)`` (:class:`~hmpc_pin.sim.disturbances.CoulombViscousFriction`, or
        ``None``); each is defined by its compiled form alone, so no check that the two agree;
        ``None`` instead of the pair when the disturbance has any other term (a user
        callable, two friction terms), which is then evaluated term by term.
    """
    terms = _terms(disturbance)
    pulses, friction = [], []
    for term in terms:
        if isinstance(term, TimeOnly):
            pulses.append(term)
        elif isinstance(term, CoulombViscousFriction):
            ab = _friction_of(term, n)
            if ab is None:
                return None  # let the plain evaluation raise its own error
            friction.append(ab)
        else:
            return None
    if len(friction) > 1:
        return None
    return pulses, (friction[0] if friction else None)


class RK4Plant:
    """Classical RK4 integration of a Pinocchio model over one control period.

    The plant is the compiled core's (``cpp/include/hmpc/rk4_plant.hpp``, ``RK4Plant``, the
    closed loop's Plant port; its period ``cpp/src/rk4.cpp``; module docstring): its state
    lives there, one C++ call per period, with the disturbance's port (compiled, or called as
    ``d(t, q, dq)`` at every stage from C++); Pinocchio's compiled ABA, or its Python ABA
    for a model with mimic joints. The compiled loop advances :attr:`port` itself
    (:meth:`loop_port`).

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot` (its own ``model``/``data``).
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for none.
        Ts: Control period [s] (the torque is held over it).
        dt: Integration step [s]; must divide ``Ts`` (default 1 ms).
        backend: Deprecated since 0.3, without effect (the period is always compiled):
            ``"auto"`` and ``"native"`` silently, ``"python"`` with a
            :class:`DeprecationWarning`.
        joint_dynamics: Apply the robot's joint damping and Coulomb friction (the
            URDF's ``<dynamics>``; default ``True``).
        coulomb: ``"stick-slip"`` (default) or ``"sign"``: the Coulomb friction's law
            (:data:`COULOMB_LAWS`, module docstring).

    Attributes:
        native: ``True`` (kept for callers of 0.2).
        port: The compiled plant (``hmpc_pin._core.RK4Plant``) that holds the state and
            advances it.
    """

    name = "rk4"
    native = True
    _was_reset = False

    def __init__(
        self,
        robot: Robot,
        disturbance=None,
        Ts: float = 0.01,
        dt: float = 0.001,
        backend: str = "auto",
        joint_dynamics: bool = True,
        coulomb: str = "stick-slip",
    ):
        if coulomb not in COULOMB_LAWS:
            raise ConfigError("plant.coulomb", f"{coulomb!r}; expected one of {COULOMB_LAWS}")
        self.coulomb = coulomb
        n = robot.nq
        self.joint_dynamics = _joint_terms(robot, joint_dynamics)
        substeps = substeps_per_period(Ts, dt)
        deprecated_backend(backend, "plant.backend")
        self.nq = self.n = n
        self.robot = robot
        self.Ts = float(Ts)
        self.model, self.data = robot.model, robot.data
        disturbance = disturbance if disturbance is not None else ZeroDisturbance(n)
        self.disturbance = disturbance
        self.h = Ts / substeps
        self.substeps = substeps
        self.port = self._make_port()

    def _make_port(self):
        """The compiled plant, on the compiled dynamics or (mimic joints, which Pinocchio
        4.1 restores badly from a serialized model) on Pinocchio's Python ABA."""
        core = load_native()
        if self.robot.mimic_joints:
            robot, model, data = self.robot, self.model, self.data
            kernel = core.RK4(None, self.n, lambda q, v, u: robot.aba(model, data, q, v, u))
        else:
            kernel = core.RK4(model_string(self.robot))
        if self.joint_dynamics is not None:
            kernel.set_joint_dynamics(*self.joint_dynamics)
        kernel.stick_slip = self.coulomb == "stick-slip"
        port = core.RK4Plant(kernel, self.Ts, self.substeps)
        port.set_disturbance(disturbance_port(self.disturbance, self.n))
        return port

    @property
    def fused(self) -> bool:
        """Whether the disturbance's terms are evaluated fused (else called per stage)."""
        return bool(self.port.fused)

    def loop_port(self) -> object:
        """The compiled plant the closed loop advances itself (:attr:`port`), or ``None``
        when a method of this plant was replaced (e.g. by a spy: the loop then calls this
        object as a plant)."""
        methods = ("advance", "disturbance_now", "applied_disturbance", "reset")
        return None if replaced(self, RK4Plant, *methods) else self.port

    @property
    def q(self) -> FloatArray:
        """The joint angles [rad] at :attr:`t`."""
        return self.port.q

    @property
    def dq(self) -> FloatArray:
        """The joint velocities [rad/s] at :attr:`t`."""
        return self.port.dq

    @property
    def k(self) -> int:
        """The periods advanced since :meth:`reset`."""
        return self.port.k

    @property
    def t0(self) -> float:
        """The time of the last :meth:`reset` [s]."""
        return self.port.t0

    @property
    def t(self) -> float:
        """The current time ``t0 + k·Ts`` [s]."""
        return self.port.t

    @property
    def events(self) -> int:
        """The Coulomb events located since the plant was built (velocity sign changes,
        sticking, breakaway; ``coulomb = "stick-slip"``)."""
        return self.port.events

    def __getstate__(self) -> dict:
        """Picklable: the compiled plant is rebuilt from the robot on unpickling, at the
        state it had."""
        state = self.__dict__.copy()
        port = state.pop("port")
        state["_state"] = (port.q, port.dq, port.t0, port.k) if self._was_reset else None
        return state

    def __setstate__(self, state: dict) -> None:
        saved = state.pop("_state", None)
        self.__dict__.update(state)
        self.port = self._make_port()
        if saved is not None:
            q, dq, t0, k = saved
            self.port.reset(q, dq, t0)
            self.port.k = k

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s]."""
        q, dq = np.array(q0, dtype=float), np.array(dq0, dtype=float)
        if q.shape != (self.n,) or dq.shape != (self.n,):
            raise DimensionError(
                f"plant state of shapes {q.shape}, {dq.shape}; expected ({self.n},)"
            )
        self.port.reset(q, dq, float(t0))
        self._was_reset = True

    def disturbance_now(self) -> FloatArray:
        """:math:`d(t, q, \\dot q)` [N·m] at the current time and state (compiled: the
        time-only terms at stage 0 of the period, t itself, minus the friction; else the
        disturbance called)."""
        return self.port.disturbance_now()

    def applied_disturbance(self, d: FloatArray) -> FloatArray:
        """The disturbance [N·m] applied at the start of the period :meth:`advance` just
        integrated, from ``d`` = :meth:`disturbance_now` there: they differ only at a joint
        that started the period at rest with a Coulomb term of the disturbance
        (``coulomb = "stick-slip"``), where :math:`\\mathrm{sgn}\\,0 = 0` gives no friction
        while the plant applied its share :math:`b_i/(F_i + b_i)` of the holding torque
        :math:`\\phi_i` (the torque that keeps the stuck joints still under the period's
        torque, :math:`|\\phi_i| \\le F_i + b_i`), or :math:`-b_i s_i` when it broke away
        with sign :math:`s_i` (:math:`F_i` the joint's own Coulomb friction, :math:`b_i` the
        disturbance's). The run records this value as its ``d``."""
        return self.port.applied_disturbance(np.asarray(d, dtype=float))

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Integrate over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``.

        Raises:
            SimulationError: Called before :meth:`reset`.
            DimensionError: ``tau`` is not of shape (n,).
        """
        tau = held_torque(self, tau)
        return self.port.advance(tau)


class EulerPlant:
    """Semi-implicit Euler integration of a Pinocchio model over one control period.

    Per step of ``h = dt``: :math:`\\dot q \\leftarrow \\dot q + h\\,\\mathrm{ABA}(q, \\dot q,
    \\tau + d(t, q, \\dot q) - B\\dot q - F\\,\\mathrm{sgn}\\,\\dot q)`, then
    :math:`q \\leftarrow q + h\\dot q`.

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot`.
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m]; ``None`` for none.
        Ts: Control period [s].
        dt: Integration step [s]; must divide ``Ts``.
        joint_dynamics: Apply the robot's joint damping and Coulomb friction,
            :math:`-B\\dot q - F\\,\\mathrm{sgn}\\,\\dot q` (default ``True``).
    """

    name = "euler"
    native = False
    _was_reset = False

    def __init__(
        self,
        robot: Robot,
        disturbance=None,
        Ts: float = 0.01,
        dt: float = 0.001,
        joint_dynamics: bool = True,
    ):
        self.nq = self.n = robot.nq
        self.joint_dynamics = _joint_terms(robot, joint_dynamics)
        self.robot = robot
        self.Ts = float(Ts)
        self.substeps = substeps_per_period(Ts, dt)
        self.h = self.Ts / self.substeps
        self.model, self.data = robot.model, robot.data
        self.disturbance = disturbance if disturbance is not None else ZeroDisturbance(self.n)
        self.t0, self.k, self.t = 0.0, 0, 0.0
        self.q, self.dq = np.zeros(self.n), np.zeros(self.n)

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s]."""
        _reset_state(self, q0, dq0, t0)

    def disturbance_now(self) -> FloatArray:
        """:math:`d(t, q, \\dot q)` [N·m] at the current time and state."""
        return self.disturbance(self.t, self.q, self.dq)

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Integrate over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``.

        Raises:
            SimulationError: Called before :meth:`reset`.
            DimensionError: ``tau`` is not of shape (n,).
        """
        tau = held_torque(self, tau)
        q, dq, t, h = self.q, self.dq, self.t, self.h
        model, data, aba, dist = self.model, self.data, self.robot.aba, self.disturbance
        joint = self.joint_dynamics
        for s in range(self.substeps):
            u = tau + dist(t + s * h, q, dq)
            if joint is not None:
                u = u - load_native().joint_torque(joint[0], joint[1], dq)
            dq = dq + h * aba(model, data, q, dq, u)
            q = q + h * dq
        self.k += 1
        self.t = self.t0 + self.Ts * self.k
        self.q, self.dq = q, dq
        return q, dq


def choose_step(
    make_plant,
    Ts: float,
    samples,
    tolerance: float,
    periods: int = 1,
    max_divisions: int = 64,
    pilot=None,
    min_divisions: int = 1,
) -> tuple[float, float]:
    """The largest step :math:`h = T_s/m` (m = 1, 2, ...) whose error over a run of
    ``periods`` periods stays within ``tolerance`` [rad] (``[plant] tolerance``).

    Each period's error is estimated by step doubling: from a sample's state, one period
    with :math:`h` and one with :math:`h/2`, the torque held,
    :math:`e_k(h) = \\max(\\|q_h - q_{h/2}\\|_\\infty,
    \\ T_s \\|\\dot q_h - \\dot q_{h/2}\\|_\\infty)` (the velocity's error weighted by the
    period, over which it moves the joints; for a method of order p, :math:`q_h - q_{h/2}`
    is :math:`1 - 2^{-p}` of :math:`h`'s own error), and the run's error by the worst
    period's error added up over the run,

    .. math::

        E(h) = K \\max_k e_k(h) \\quad (K = \\text{periods}),

    a bound on the run's state error when nothing amplifies it (a closed loop damps it:
    its error against a fine integration is below :math:`E`). With ``pilot``, a step must
    also keep ``pilot(h)`` [rad] within the tolerance (the error of a stretch of the run
    itself: a closed loop's start far from the samples). The steps are tried from the
    longest; a step whose period diverges (not finite) fails.

    Args:
        make_plant: ``make_plant(h)``, a new plant advancing ``Ts`` per call with step ``h``.
        Ts: The period [s].
        samples: ``(t, q, dq, tau)`` tuples: start time [s], state [rad, rad/s] and the torque
            held [N·m] of the periods checked.
        tolerance: The largest error :math:`E` accepted [rad].
        periods: The run's periods :math:`K`.
        max_divisions: The finest step tried is ``Ts / max_divisions``.
        pilot: ``pilot(h)``, a further error [rad] of the step ``h``, or ``None``.
        min_divisions: The longest step tried is ``Ts / min_divisions`` (a bound the
            caller knows, e.g. the URDF damping's stability limit).

    Returns:
        ``(h, E(h))`` (``E`` the larger of the two errors with ``pilot``).

    Raises:
        ConfigError: (``plant.tolerance``) no step down to ``Ts / max_divisions`` is within
            it, naming the error reached there.
    """
    samples = list(samples)
    err = np.inf
    for m in range(max(1, min_divisions), max_divisions + 1):
        coarse, fine = make_plant(Ts / m), make_plant(Ts / (2 * m))
        worst = 0.0
        for t, q, dq, tau in samples:
            coarse.reset(q, dq, t)
            fine.reset(q, dq, t)
            with np.errstate(all="ignore"):
                qc, vc = coarse.advance(tau)
                qf, vf = fine.advance(tau)
                e = max(np.abs(qc - qf).max(), Ts * np.abs(vc - vf).max())
            worst = max(worst, e if np.isfinite(e) else np.inf)
            if periods * worst > tolerance:
                break
        err = periods * worst
        if err <= tolerance and pilot is not None:
            err = max(err, float(pilot(Ts / m)))
        if err <= tolerance:
            return Ts / m, float(err)
    raise ConfigError(
        "plant.tolerance",
        f"{tolerance:g} rad is not reached by any plant step down to Ts/{max_divisions} = "
        f"{Ts / max_divisions:g} s (error {err:.3g} rad there); expected a larger tolerance, "
        "or a fixed plant.dt",
    )


#: Plant classes by ``[plant] integrator`` name (and ``"mujoco"``: the MuJoCo plant,
#: registered by :mod:`.mujoco`, chosen by ``[plant] engine``; it needs the ``mujoco`` extra).
PLANTS: dict[str, type] = {cls.name: cls for cls in (RK4Plant, EulerPlant)}
