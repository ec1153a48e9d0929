"""The hierarchical multiloop MPC (paper Figure 1): inverse dynamics + NDO + per-joint MPC.

At every control instant :math:`t_k`:

1. Pinocchio gives :math:`M(q_k)` and :math:`C\\dot q_k + G` at the measured state.
2. The NDO (Eq 13) is advanced over the period that just ended with the torque
   that was held over it, giving :math:`\\hat d_k`.
3. Each joint's MPC (Eq 25–26) chooses its acceleration :math:`v_i` from the
   reference sampled at :math:`t_k + jT_s,\\ j = 1..N`.
4. Inverse dynamics (Eq 4): :math:`\\tau = M(q)v + C(q,\\dot q)\\dot q + G(q) - \\hat d`.

With joint damping :math:`B` and Coulomb friction :math:`F` in the model (the URDF's
``<dynamics>``, :attr:`MPCSettings.joint_dynamics`), :math:`C\\dot q + G` reads
:math:`C\\dot q + G + B\\dot q + F\\,\\mathrm{sgn}\\,\\dot q` in steps 2 and 4, and a damped
joint j gets the extra torque :math:`(g_j - 1) m_j v_j`, :math:`m_j = 1/(M^{-1})_{jj}`,
:math:`g_j = a_jT_s / (1 - e^{-a_jT_s})`, :math:`a_j = b_j/m_j`: with the torque held over
the period and :math:`b_j\\dot q_k` compensated at the sampled velocity, the damped joint
then gains exactly the velocity :math:`v_jT_s` the MPC's double integrator predicts (the
zero-order-hold discretisation of :math:`m_j\\dot w = -b_jw + u`).
"""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ..compensation.base import Compensation, check_compensation, step_compensation
from ..compensation.observers import default_observer
from ..exceptions import DimensionError, HmpcError, NonFiniteError, ValidityWarning
from ..model.robot import Robot, damping_time_constants
from ..mpc.condensed import CondensedMPC, JointQPs, StateLimits
from ..native import deprecated_backend, model_string, replaced
from ..native import load as load_native
from ..tasks.base import Reference, as_reference, check_reference_size, reference_port
from .base import AppliedTorque, config_parts, not_reset
from .mpc_settings import (
    MODEL_AT,
    QP_LAYOUTS,
    MPCSettings,
    check_settings,
    state_limits,
)

__all__ = [
    "MODEL_AT",
    "QP_LAYOUTS",
    "HierarchicalMPC",
    "MPCSettings",
    "check_settings",
    "state_limits",
    "warn_fast_damping",
]

FloatArray = NDArray[np.float64]


def warn_fast_damping(robot: Robot, Ts: float) -> None:
    """A :class:`~hmpc_pin.exceptions.ValidityWarning` naming each joint of ``robot`` (the
    arm as simulated or built) whose URDF damping time constant (at mid-range,
    :func:`~hmpc_pin.model.robot.damping_time_constants`) is below :math:`2T_s` [s], for a
    controller that does not compensate the joint dynamics (``joint_dynamics = False``):
    tracking degrades there."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, 0.0)
    hi = np.where(np.isfinite(robot.upper), robot.upper, 0.0)
    tc = damping_time_constants(robot, 0.5 * (lo + hi))
    for j in np.flatnonzero(tc < 2 * Ts):
        warnings.warn(
            f"joint {robot.joint_names[j]!r}: its URDF damping's time constant "
            f"1/(b (M^-1)_jj) = {tc[j]:.3g} s is below 2 Ts = {2 * Ts:g} s and the "
            "controller does not compensate it (joint_dynamics = false): tracking "
            "degrades; set controller.joint_dynamics = true or lower Ts",
            ValidityWarning,
            stacklevel=3,
        )


class HierarchicalMPC(AppliedTorque):
    """Inverse dynamics + disturbance compensation + one ProxSuite MPC per joint (``hmpc*`` kinds).

    Args:
        robot: The controller's model of the arm (its :class:`~hmpc_pin.model.robot.Robot`).
        settings: The MPC's :class:`MPCSettings` (checked when built, with the
            :class:`~hmpc_pin.exceptions.ConfigError` a config file gets); the default is
            the paper's controller (Section 4).
        compensation: The disturbance compensation
            (:class:`~hmpc_pin.compensation.base.Compensation`): its estimate has one entry
            per joint and its period, if it has one (``Ts``), is ``settings.Ts``. Default:
            the paper's observer, Chen's :math:`Y` (Eq 28) with gain 100, which is proven
            for planar serial arms only: on any other arm it comes with a
            :class:`~hmpc_pin.exceptions.ValidityWarning` (as in a config).
        limits: The joint limits imposed on the predictions as soft state constraints:
            ``"urdf"`` (default: the robot's position and velocity limits), a
            :class:`~hmpc_pin.mpc.condensed.StateLimits`, or ``None`` (none).

    Raises:
        ConfigError: A setting is out of range, or the compensation's period differs.
        DimensionError: The compensation is for another number of joints.

    Attributes:
        disturbance_estimate: :math:`\\hat d` [N·m], shape (n,), updated by :meth:`step`
            (the observer's estimate; for ``hmpc-ism*`` the ISM torque :math:`-M u_{ism}`;
            zeros without compensation).
        v: The last commanded accelerations [rad/s²], shape (n,).
        tau: The last torque [N·m], shape (n,).
            These three are read-only views of the compiled step's memory (:attr:`data`),
            updated in place by every step; copy one to keep it.
        limits: The joint limits imposed on each MPC's prediction as soft state
            constraints (:class:`~hmpc_pin.mpc.condensed.StateLimits`), ``None`` if disabled.

    Example:
        >>> robot = hmpc_pin.load_robot("robots/planar3.urdf")
        >>> ctrl = hmpc_pin.HierarchicalMPC(robot)
        >>> ctrl.reset(q0, dq0)
        >>> tau = ctrl.step(t, q, dq, hmpc_pin.SineReference(robot.nq))
    """

    def __init__(
        self,
        robot: Robot,
        settings: MPCSettings | None = None,
        compensation: Compensation | None = None,
        limits: StateLimits | str | None = "urdf",
    ):
        self.robot = robot
        if settings is not None and not isinstance(settings, MPCSettings):
            settings, compensation, limits = config_parts(
                settings, robot, "HierarchicalMPC", "MPCSettings"
            )
        self.settings = settings = settings if settings is not None else MPCSettings()
        deprecated_backend(settings.backend, "controller.backend")
        n = robot.nq
        self.n = n
        self.compensation = (
            compensation if compensation is not None else default_observer(n, settings.Ts)
        )
        check_compensation(self.compensation, robot, settings.Ts, "HierarchicalMPC")
        v_min, v_max = settings.bounds(n)
        self.mpc = CondensedMPC(
            settings.Ts, settings.N, settings.Nc, settings.Q, settings.R, settings.P
        )
        self.limits = state_limits(robot) if isinstance(limits, str) else limits
        self.qps = JointQPs(
            self.mpc,
            v_min,
            v_max,
            robot.joint_names,
            eps_abs=settings.eps_abs,
            max_iter=settings.max_iter,
            limits=self.limits,
            layout=settings.qp_layout,
        )
        N = settings.N
        self._offsets = settings.Ts * np.arange(1, N + 1)
        self._times = np.empty(N)
        # The step's memory (hmpc_pin._core.StepData, cpp/include/hmpc/step_data.hpp), kept
        # across the compiled steps built for it: the state and the reference horizon the
        # step starts from (written here when the reference is sampled in Python), v, τ, d̂,
        # M and C q̇ + G (read-only views, updated in place by the compiled step).
        self._data = data = load_native().StepData(n, N)
        self._stack, self._q, self._dq = data.stack, data.q, data.dq
        self._ref_out = (data.q_ref, data.dq_ref)
        self._ref_shape = (N, n)
        self._shape = (n,)
        self._reference: object = None
        self._ref: Reference | None = None
        self._native_ref = False
        self._native_step: Callable[[float, Any, Any], None] | None = None
        # Models the compiled dynamics cannot load (mimic joints): M and C q̇ + G in Python.
        self._python_dynamics = bool(robot.mimic_joints)
        self.disturbance_estimate = data.d_hat
        self.v = data.v
        self.tau = data.tau
        self._was_reset = False
        self._core = None
        self._make_core()

    @property
    def compensation(self) -> Compensation:
        """The disturbance compensation; setting it (e.g. behind a
        :class:`~hmpc_pin.compensation.gate.FeedbackGate`) rebuilds the compiled step."""
        return self._compensation

    @compensation.setter
    def compensation(self, comp: Compensation) -> None:
        self._compensation = comp
        if hasattr(self, "_core"):
            self._make_core()

    @property
    def _started(self) -> bool:
        """Whether a step succeeded since the last :meth:`reset` (the compiled step's)."""
        return self._core is not None and bool(self._core.started)

    def compiled_controller(self, reference, measurement=None) -> Any:
        """This controller's compiled step as the compiled loop's Controller port
        (``hmpc_pin._core.StepController``, ``cpp/include/hmpc/step.hpp``) for
        ``reference``, sampled through the step's Reference port (compiled, or its
        ``_sample_horizon``); behind the Measurement port ``measurement`` if given (reset
        with this controller by its wrapper). Built after :meth:`reset`; the loop steps it
        as :meth:`step` would.

        Raises:
            SimulationError: Called before :meth:`reset`.
        """
        if reference is not self._reference:  # adapted once per reference object
            self._set_reference(reference)
        port = load_native().StepController(self._core)
        if measurement is not None:
            port.set_measurement(measurement)
        return port

    def loop_port(self, reference) -> Any:
        """The compiled loop's Controller port for ``reference``
        (:meth:`compiled_controller`), or ``None`` when :meth:`step` was replaced (a
        subclass's or an instance's, e.g. a spy: the loop then calls this object's
        ``step``)."""
        if replaced(self, HierarchicalMPC, "step"):
            return None
        return self.compiled_controller(reference)

    @property
    def native(self) -> bool:
        """Whether :meth:`step` runs compiled: always, since 0.3 (kept for old callers)."""
        return True

    @property
    def fused(self) -> bool:
        """Whether the whole step runs compiled, without calling Python: the compensation is
        compiled (the NDO of Eq 13, or none) and so is the model's dynamics. Any other compensation
        (momentum, ISM, a user class) is advanced inside the compiled step too, called
        through its Compensation port (``cpp/include/hmpc/interfaces.hpp``)."""
        return self._all_compiled

    def _make_core(self) -> None:
        """The compiled step (``cpp/src/step.cpp``), composed of the compiled components: the
        QPs are :attr:`qps`' own, the compensation is behind the step's Compensation port
        (the compiled observer itself, or the Python object through its trampoline)."""
        decoded = step_compensation(self.compensation)
        port = decoded.port
        self._all_compiled = decoded.compiled and not self._python_dynamics
        self._port = port
        model = None if self._python_dynamics else model_string(self.robot)
        core = load_native().HierarchicalStep(
            model, self.mpc.FT, self.settings.N, self.qps._core, port, self._data
        )
        if self._python_dynamics:
            core.set_model(self._python_dynamics_at)
        core.set_offsets(self._offsets)
        robot = self.robot  # how the compiled step's faults name it
        core.robot = f"the robot {robot.name!r} has {self.n} joints {robot.joint_names}"
        core.set_latency(self.settings.latency, self.settings.Ts)
        core.set_observer_model(self.settings.model_at == "start")
        b, f = self.joint_dynamics
        if b.any() or f.any():
            core.set_joint_dynamics(b, f, self.settings.Ts)
        self._core = core
        self._reference = None  # the reference's port is set on the next step
        self._compile_step(None)  # the compiled step of the former core is gone
        self.effort_limit = self.effort_limit

    @property
    def joint_dynamics(self) -> tuple[FloatArray, FloatArray]:
        """``(B, F)``: the joint damping [N·m·s/rad] and Coulomb friction [N·m] the step
        compensates (the model's, :attr:`~hmpc_pin.model.robot.Robot.joint_damping` and
        ``joint_friction``; zeros with ``settings.joint_dynamics = False``)."""
        n = self.n
        if not self.settings.joint_dynamics:
            return np.zeros(n), np.zeros(n)
        robot = self.robot
        b = np.asarray(getattr(robot, "joint_damping", np.zeros(n)), dtype=float)
        f = np.asarray(getattr(robot, "joint_friction", np.zeros(n)), dtype=float)
        return b.copy(), f.copy()

    @AppliedTorque.effort_limit.setter  # type: ignore[attr-defined]
    def effort_limit(self, limit: FloatArray | None) -> None:
        AppliedTorque.effort_limit.fset(self, limit)  # type: ignore[attr-defined]
        if self._core is not None:
            self._core.set_effort(np.full(self.n, np.inf) if limit is None else self._effort[1])

    @property
    def data(self) -> Any:
        """The compiled step's memory (``hmpc_pin._core.StepData``; the step computes, this
        object holds what it reads and writes), the same object for the controller's life.
        Numpy views of it: ``q``, ``dq`` (n,), the state the last step started from (the
        measurement, or with a latency its prediction) [rad, rad/s]; ``q_ref``, ``dq_ref``
        (N, n), its reference horizon :math:`r(t + jT_s)`, :math:`\\dot r(t + jT_s)`,
        j = 1..N; read-only: ``v`` [rad/s²], ``tau`` [N·m] (Eq 4), ``d_hat`` [N·m], and
        ``M``, ``nle`` (the model's M and :math:`C\\dot q + G`, kept only when Pinocchio's
        Python API computes them). The QPs' inputs are ``qps.solution``
        (:class:`~hmpc_pin.mpc.condensed.JointQPs`)."""
        return self._data

    @property
    def Ts(self) -> float:
        """Control period [s]."""
        return self.settings.Ts

    @property
    def state(self) -> tuple[FloatArray, FloatArray]:
        """``(q, q̇)`` [rad, rad/s] the MPC and Eq (4) started from at the last step: the
        measurement, or with a latency its prediction (copies)."""
        return self._q.copy(), self._dq.copy()

    @property
    def latency(self) -> float:
        """The measurement latency L [s] the step compensates (:class:`MPCSettings`)."""
        return self.settings.latency

    def set_latency(self, latency: float) -> None:
        """Compensate a measurement latency of ``latency`` [s] from the next :meth:`reset`
        on (e.g. the one a real-time loop measured); 0 switches it off.

        Raises:
            ConfigError: ``latency`` is not a finite number >= 0.
        """
        from dataclasses import replace

        self.settings = replace(self.settings, latency=float(latency))
        self._core.set_latency(self.settings.latency, self.settings.Ts)

    def reset(self, q0: FloatArray, dq0: FloatArray) -> None:
        """Start a new run from the state ``(q0, dq0)``; the estimate restarts at zero."""
        q0 = self.robot.check_vector("q0", q0)
        dq0 = self.robot.check_vector("dq0", dq0)
        if self._port is None:  # no compensation in the step: d̂ = 0
            self.compensation.reset(q0, dq0)
        # The compensation restarted through the step's port; v, τ and d̂ are the compiled
        # step's buffers, updated in place from now on.
        self._core.reset(q0, dq0)
        self._was_reset = True

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> np.ndarray:
        """Compute the torque for the measured state at time ``t``.

        Call once per control period :math:`T_s`, after :meth:`reset`. The
        observer assumes the torque returned by the previous call was held since.

        One compiled step (``cpp/src/step.cpp``): the horizon's gradients, M and
        :math:`C\\dot q + G`, the compensation's estimate, the joint QPs and Eq (4). The
        compensation is advanced inside it, through its Compensation port: the compiled NDO
        of Eq 13 without Python, any other (momentum, ISM, a user class) by a call of its
        ``update`` from the compiled step.

        For a reference with a compiled port (the package's references), the first call
        binds the compiled step to this controller as ``ctrl.step``
        (``hmpc_pin._core.CompiledStep``, its ``__func__`` this method): later calls with
        that reference, a float ``t`` and float64 vectors run it without a Python frame;
        any other call (another reference, keywords, other types or shapes) comes here. A
        subclass's ``step``, or one set on the instance, is never replaced.

        Args:
            t: Time [s].
            q: Measured joint positions [rad], shape (n,).
            dq: Measured joint velocities [rad/s], shape (n,).
            reference: A :class:`~hmpc_pin.tasks.base.Reference` (anything else
                :func:`~hmpc_pin.tasks.base.as_reference` adapts, once per object).

        Returns:
            Joint torques :math:`\\tau` [N·m], shape (n,), Eq (4).

        Raises:
            NonFiniteError: ``t``, ``q``, ``dq`` or the reference is not finite.
            DimensionError: ``q``, ``dq`` or the reference has the wrong shape.
            SolverError: A joint QP did not report solved.
            SimulationError: Called before :meth:`reset`.
        """
        if reference is not self._reference:  # adapted once per reference object
            self._set_reference(reference)
        native_step = self._native_step
        if native_step is not None:  # the whole step in one call
            try:
                native_step(t, q, dq)
            except TypeError as exc:  # not convertible to a float vector, or the compensation's
                self._not_vectors(q, dq, exc)
            return self.tau.copy()
        core = self._core
        if not math.isfinite(t):
            raise NonFiniteError("t", t)
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        if q.shape != self._shape or dq.shape != self._shape:
            self.robot.check_vector("q", q)  # raises the precise error
            self.robot.check_vector("dq", dq)
        self._q[...] = q
        self._dq[...] = dq
        self._sample_horizon(t)
        core.step(self._stack, t)
        return self.tau.copy()

    def warm_up(self, t: float, q: np.ndarray, dq: np.ndarray, reference) -> None:
        """Run :meth:`step` on ``(t, q, dq)`` and undo it: the next step computes what it
        would have computed without this call, but finds its memory (the compiled step's
        matrices, the QPs' workspaces, the Python path) in the caches.

        The real-time loop calls it in the slack before an MPC cycle with the last measured
        state (:class:`~hmpc_pin.realtime.loop.LoopSettings` ``warm_up``): a step after a
        sleep otherwise starts on caches other processes have used. Restored afterwards:
        v, τ, d̂, M, C q̇ + G, the horizon stack and solution, the slacks, the QPs' counters
        and the compiled observer's state, the QPs' memory (ProxSuite's warm starts, the
        active sets the shortcuts remembered), so that the next step's answers are, bit for
        bit, those without this call. The compiled step's own carry-over (the joint-dynamics
        torque, the latency's torque histories) is restored too. Does nothing before the first
        :meth:`step` after :meth:`reset`, or with a compensation advanced from Python (its
        state is its own). Errors of the dry step are dropped: the real step reports them.
        """
        if not (self._started and self._all_compiled):
            return
        ndo = self._port
        data = copy.copy(self._data)  # the step's memory (a copy of the StepData)
        core = self.qps._core
        solution = core.state  # the QPs' solution and slacks (copies)
        counters = copy.copy(core.stats)  # the QPs' counters (JointQPsStats)
        memory = core.save_memory()  # warm starts, remembered active sets
        ndo_state = ndo.state if ndo is not None else None
        step_core = self._core
        # copies, independent of the compiled step's own vectors
        carried = tuple(
            np.array(x, copy=True)
            if isinstance(x, np.ndarray)
            else [np.array(a, copy=True) for a in x]
            if isinstance(x, list)
            else x
            for x in step_core.state
        )
        try:
            self.step(t, q, dq, reference)
        except HmpcError:
            pass
        finally:
            self._data.assign(data)
            core.state = solution
            core.stats = counters
            core.restore_memory(memory)
            step_core.state = carried
            if ndo is not None:
                ndo.state = ndo_state

    def _python_dynamics_at(self, q: FloatArray, dq: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(M, C q̇ + G)`` at ``(q, dq)`` from Pinocchio's Python API (models the compiled
        dynamics cannot load; called by the compiled step, which keeps them in its data)."""
        M = self.robot.mass_matrix(q)
        return M, pin.nonLinearEffects(self.robot.model, self.robot.data, q, dq)

    def _sample_horizon(self, t: float) -> None:
        """The horizon rows of the step's stack, :math:`r(t + jT_s)`, :math:`\\dot r(t +
        jT_s)`, j = 1..N, from a reference without a compiled port (sampled here, in one
        ``sample_many`` call; the compiled loop calls this through its Reference port).

        Raises:
            DimensionError: ``sample_many`` returned arrays of another shape.
        """
        times = np.add(self._offsets, t, self._times)
        out = self._ref_out
        q_ref, dq_ref = self._ref.sample_many(times, out)  # type: ignore[union-attr]
        if q_ref is not out[0]:
            if q_ref.shape != self._ref_shape or dq_ref.shape != self._ref_shape:
                raise DimensionError(
                    f"reference.sample_many returned q_ref of shape {q_ref.shape} and "
                    f"dq_ref of shape {dq_ref.shape} but the horizon needs "
                    f"{self._ref_shape} ({self.n} joints); return two arrays of shape "
                    f"(len(times), {self.n})"
                )
            out[0][:] = q_ref
            out[1][:] = dq_ref

    def _set_reference(self, reference) -> None:
        """Adapt ``reference`` (:func:`~hmpc_pin.tasks.base.as_reference`) and give the
        compiled step its Reference port: its compiled one
        (:func:`~hmpc_pin.tasks.base.reference_port`), else :meth:`_sample_horizon`.

        Raises:
            SimulationError: Called before :meth:`reset`.
        """
        if not self._was_reset:
            raise not_reset(self)
        check_reference_size(reference, self.n, "HierarchicalMPC.step")
        self._ref = as_reference(reference)
        self._reference = reference
        port = reference_port(self._ref)
        self._native_ref = port is not None
        # the compiled step's bound method, looked up here once (the step's Python frame)
        self._native_step = self._core.step_t if port is not None else None
        self._core.set_reference(self._sample_horizon if port is None else port)
        self._compile_step(reference if port is not None else None)

    def _compile_step(self, reference) -> None:
        """Make ``self.step`` the compiled step for ``reference`` (``hmpc_pin._core.CompiledStep``:
        :meth:`step` without its Python frame, for a reference with a compiled port; any other
        call goes through :meth:`step`), or drop it (``reference`` None). Nothing is done where
        :meth:`step` was replaced: a subclass's override or one set on the instance is kept."""
        own = self.__dict__.get("step")
        if type(self).step is not HierarchicalMPC.step or not (
            own is None or isinstance(own, load_native().CompiledStep)
        ):
            return
        if reference is None:
            self.__dict__.pop("step", None)
        else:
            self.__dict__["step"] = self._core.compiled_step(reference, HierarchicalMPC.step, self)

    def _not_vectors(self, q, dq, exc: TypeError) -> None:
        """Raise the error of ``q`` or ``dq`` that is not a vector of n floats, or ``exc``
        (raised inside the step, e.g. by a Python compensation) if they are."""
        self.robot.check_vector("q", q)
        self.robot.check_vector("dq", dq)
        if "incompatible function arguments" not in str(exc):
            raise exc
        raise DimensionError(f"q and dq must be float vectors of shape ({self.n},)") from None
