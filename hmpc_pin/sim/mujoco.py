"""MuJoCo as the plant: a second physics engine on the same URDF as the controller's model.

The plant of :mod:`~hmpc_pin.sim.plants` integrates the controller's own Pinocchio model (ABA), with
friction an added formula. :class:`MuJoCoPlant` instead compiles the arm's URDF with
MuJoCo (``MjSpec``) and steps it with MuJoCo's integrator, so that the arm's joint
friction (``frictionloss``, a dry-friction constraint), viscous damping, rotor armature,
joint-limit constraints and contacts with an obstacle are properties of the simulated
arm, computed by another engine than the controller's model. Per MuJoCo step of
``h = dt`` with the torque :math:`\\tau` held over the control period:

.. math::

    M(q)\\ddot q + C(q,\\dot q)\\dot q + G(q) = \\tau + d(t, q, \\dot q)
        + \\tau_\\mathrm{passive} + J_c^T f_c + \\tau_\\mathrm{friction}
        + \\tau_\\mathrm{limit}, \\qquad (1)

where :math:`d` is the config's ``[disturbance]`` (applied as the generalized force
``qfrc_applied``), :math:`\\tau_\\mathrm{passive} = -D\\dot q` the joint damping and the
three constraint terms (contacts, dry joint friction, joint limits) MuJoCo's soft
constraint solver. Everything beyond :math:`\\tau + d` is what the controller's model
does not know: :meth:`MuJoCoPlant.disturbance_now` reports it with :math:`d`, the
total the disturbance observer estimates, and :attr:`MuJoCoPlant.contact_force`
the contact part :math:`J_c^T f_c` alone.

The URDF is made consistent with the controller's model before MuJoCo sees it:

* ``package://`` and relative mesh paths are resolved to files (MuJoCo's URDF reader
  does not know ROS packages), or meshes left out (``geometry = "none"``);
* locked joints (``[robot] locked_joints``) become fixed joints at their locked
  position, as ``pin.buildReducedModel`` does;
* ``<mimic>``: a follower the controller's model makes Pinocchio's mimic joint of its
  leader (:attr:`~hmpc_pin.model.robot.Robot.mimic_joints`) keeps the tag, which MuJoCo
  turns into a joint equality constraint :math:`q_f = m q_l + o`, made stiff (see
  :func:`mujoco_model`); a follower the controller controls as an independent coordinate
  loses it; a locked follower is fixed with its leader;
* ``<dynamics damping friction>``: imported as ``dof_damping`` and ``dof_frictionloss``
  of the joint's dof (matched by name) unless ``import_urdf_dynamics = False``, as the
  Pinocchio plants apply them (:attr:`~hmpc_pin.model.robot.Robot.joint_damping`);
* the joints are matched to the controller's by name, not by order.

``mujoco`` is an optional dependency (extra ``mujoco``); it is imported when a plant is
built.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DimensionError, URDFError
from ..model.robot import Robot
from .disturbances import ZeroDisturbance
from .mjcf import (
    ARM_CONAFFINITY,
    ARM_CONTYPE,
    MESH_SUFFIXES,
    MIMIC_SOLIMP,
    MIMIC_TIMECONST,
    OBSTACLE_CONAFFINITY,
    OBSTACLE_CONTYPE,
    import_mujoco,
    mujoco_model,
    resolve_mesh_path,
    urdf_for_mujoco,
)
from .mujoco_settings import GEOMETRY_SOURCES, MUJOCO_INTEGRATORS, MuJoCoSettings, Obstacle
from .plants import PLANTS, held_torque, split_disturbance, substeps_per_period

# the settings (.mujoco_settings) and the URDF translation (.mjcf) are re-exported here
__all__ = [
    "ARM_CONAFFINITY",
    "ARM_CONTYPE",
    "GEOMETRY_SOURCES",
    "MESH_SUFFIXES",
    "MIMIC_SOLIMP",
    "MIMIC_TIMECONST",
    "MUJOCO_INTEGRATORS",
    "OBSTACLE_CONAFFINITY",
    "OBSTACLE_CONTYPE",
    "MuJoCoPlant",
    "MuJoCoSettings",
    "Obstacle",
    "import_mujoco",
    "mujoco_model",
    "mujoco_version",
    "resolve_mesh_path",
    "urdf_for_mujoco",
]

FloatArray = NDArray[np.float64]


def mujoco_version() -> str:
    """The installed MuJoCo version (for the result's metadata)."""
    return str(import_mujoco().__version__)


def _joint_bodies(model, joint_names) -> list[list[int]]:
    """For each joint, the MuJoCo bodies it moves rigidly (its body and the fixed bodies
    below it): the links Pinocchio merges into that joint's body."""
    owner = {}
    for b in range(1, model.nbody):
        k = b
        while k > 0 and model.body_jntnum[k] == 0:
            k = model.body_parentid[k]
        owner[b] = model.body_jntadr[k] if k > 0 else -1
    groups = []
    for name in joint_names:
        j = model.joint(name).id
        groups.append([b for b, o in owner.items() if o == j])
    return groups


def _inertia_factors(robot: Robot) -> np.ndarray | None:
    """Per-joint factors by which ``robot``'s link inertias are its URDF's scaled
    (:meth:`~hmpc_pin.model.robot.Robot.with_scaled_inertias`), or ``None`` if unscaled.

    Raises:
        URDFError: The inertias differ otherwise than by one factor per link.
    """
    from ..model.robot import load_robot

    nominal = load_robot(robot.source, robot.gravity, robot.locked_joints)
    factors = []
    for i in range(1, robot.model.njoints):
        a, b = robot.model.inertias[i], nominal.model.inertias[i]
        k = a.mass / b.mass if b.mass > 0 else 1.0
        if not (
            np.allclose(a.lever, b.lever, atol=1e-12)
            and np.allclose(a.inertia, k * b.inertia, rtol=1e-9, atol=1e-15)
        ):
            raise URDFError(
                robot.source,
                f"the plant model's link {i} differs from its URDF other than "
                "by a factor on mass and inertia; the MuJoCo plant can only scale a link",
            )
        factors.append(k)
    k = np.array(factors)
    return None if np.allclose(k, 1.0, rtol=1e-12) else k


class MuJoCoPlant:
    """The arm simulated by MuJoCo, advanced one control period at a time.

    Args:
        robot: The plant's :class:`~hmpc_pin.model.robot.Robot`: its URDF, locked joints,
            gravity and link inertias (a :meth:`~hmpc_pin.model.robot.Robot.with_scaled_inertias`
            copy scales MuJoCo's links the same way) define MuJoCo's model.
        disturbance: Callable ``d(t, q, dq) -> (n,)`` [N·m] applied as generalized force
            at every MuJoCo step; ``None`` for none.
        Ts: Control period [s] (the torque is held over it).
        dt: MuJoCo's time step ``opt.timestep`` [s]; must divide ``Ts``.
        settings: :class:`MuJoCoSettings` (friction, damping, armature, integrator,
            geometry, obstacle).

    Attributes:
        model, data: MuJoCo's ``MjModel``/``MjData``.
        contact_force: Generalized contact force :math:`J_c^T f_c` [N·m] on each joint,
            of MuJoCo's last step of the last period (zeros after :meth:`reset`).
        engine_force: Everything MuJoCo adds beyond :math:`\\tau + d` (damping, dry
            friction, limits, contacts) [N·m], of the last step of the last period.
        history: With an obstacle, ``contact_force`` at every control instant since
            :meth:`reset` (a list of arrays); empty without (contacts are off).
    """

    name = "mujoco"
    _was_reset = False
    engine = "mujoco"

    def __init__(
        self,
        robot: Robot,
        disturbance=None,
        Ts: float = 0.01,
        dt: float = 0.001,
        settings: MuJoCoSettings | None = None,
    ):
        mujoco = import_mujoco()
        self._mj = mujoco
        self.settings = settings if settings is not None else MuJoCoSettings()
        n = robot.nq
        self.nq = self.n = n
        self.robot = robot
        self.Ts = float(Ts)
        self.substeps = substeps_per_period(Ts, dt)
        self.h = self.Ts / self.substeps
        self.model = model = mujoco_model(robot, self.settings)
        model.opt.timestep = self.h
        factors = _inertia_factors(robot)
        if factors is not None:  # one factor per joint of the Pinocchio model (mimic too)
            names = list(robot.model.names)[1:]
            for k, bodies in zip(factors, _joint_bodies(model, names), strict=True):
                model.body_mass[bodies] *= k
                model.body_inertia[bodies] *= k
        self.data = mujoco.MjData(model)
        self.qadr = np.array([model.joint(j).qposadr[0] for j in robot.joint_names])
        self.vadr = np.array([model.joint(j).dofadr[0] for j in robot.joint_names])
        # MuJoCo's velocities from the controller's, q̇_mj = E q̇ (mimic followers:
        # m·q̇_leader); generalized forces back to the controller's coordinates by Eᵀ.
        index = {name: i for i, name in enumerate(robot.joint_names)}
        self._mimics = []
        E = np.zeros((model.nv, n))
        E[self.vadr, np.arange(n)] = 1.0
        for follower, (leader, mult, offset) in dict(getattr(robot, "mimic_joints", {})).items():
            j = model.joint(follower)
            self._mimics.append((j.qposadr[0], j.dofadr[0], index[leader], mult, offset))
            E[j.dofadr[0], index[leader]] = mult
        self._E = E
        self._ident = bool(
            np.array_equal(self.qadr, np.arange(n))
            and np.array_equal(self.vadr, np.arange(n))
            and model.nq == n
            and model.nv == n
        )
        self.disturbance = disturbance if disturbance is not None else ZeroDisturbance(n)
        split = split_disturbance(self.disturbance, n)
        # Time-only terms tabulated per period (none: the torque alone); ``None``: the
        # disturbance is called at every step.
        self._pulses = split[0] if split is not None and split[1] is None else None
        self._offsets = self.h * np.arange(self.substeps)
        self._contact_rows = tuple(
            int(getattr(mujoco.mjtConstraint, name))
            for name in (
                "mjCNSTR_CONTACT_FRICTIONLESS",
                "mjCNSTR_CONTACT_PYRAMIDAL",
                "mjCNSTR_CONTACT_ELLIPTIC",
            )
        )
        self._qfrc = np.zeros(model.nv)
        self._zero = np.zeros(n)
        self._contacts = self.settings.obstacle is not None
        self.t0, self.k, self.t = 0.0, 0, 0.0
        self.q, self.dq = np.zeros(n), np.zeros(n)
        self.contact_force = np.zeros(n)
        self.engine_force = np.zeros(n)
        self.history: list[np.ndarray] = []

    @property
    def version(self) -> str:
        """MuJoCo's version."""
        return str(self._mj.__version__)

    def __getstate__(self) -> dict:
        """Picklable (e.g. to run the plant in another process): all but the module."""
        state = self.__dict__.copy()
        del state["_mj"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._mj = import_mujoco()

    def reset(self, q0: FloatArray, dq0: FloatArray, t0: float = 0.0) -> None:
        """Start at ``(q0, dq0)`` [rad, rad/s] at time ``t0`` [s]."""
        q = np.array(q0, dtype=float)
        dq = np.array(dq0, dtype=float)
        if q.shape != (self.n,) or dq.shape != (self.n,):
            raise DimensionError(
                f"plant state of shapes {q.shape}, {dq.shape}; expected ({self.n},)"
            )
        m, d = self.model, self.data
        self._mj.mj_resetData(m, d)
        d.qpos[self.qadr] = q
        d.qvel[self.vadr] = dq
        for qa, va, leader, mult, offset in self._mimics:  # on their constraint
            d.qpos[qa] = mult * q[leader] + offset
            d.qvel[va] = mult * dq[leader]
        d.time = float(t0)
        self._mj.mj_forward(m, d)
        self.q, self.dq = q, dq
        self.t0, self.k, self.t = float(t0), 0, float(t0)
        self.contact_force = np.zeros(self.n)
        self.engine_force = np.zeros(self.n)
        self.history = [self.contact_force] if self._contacts else []
        self._was_reset = True

    def disturbance_now(self) -> FloatArray:
        """What the controller's model does not know [N·m]: the config's
        :math:`d(t, q, \\dot q)` now plus MuJoCo's damping, dry friction, limit and contact
        forces (of the last step of the period that ended now: they depend on the torque
        held)."""
        return np.asarray(self.disturbance(self.t, self.q, self.dq)) + self.engine_force

    def generalized_contact_force(self) -> FloatArray:
        """:math:`J_c^T f_c` [N·m] of the contacts of MuJoCo's last step, per controlled joint:
        the constraint forces of the contact rows mapped by the constraint Jacobian (and
        a mimic follower's share onto its leader)."""
        m, d = self.model, self.data
        if d.ncon == 0:
            return np.zeros(self.n)
        rows = np.isin(d.efc_type, self._contact_rows)
        force = np.where(rows, d.efc_force, 0.0)
        self._mj.mj_mulJacTVec(m, d, self._qfrc, force)
        return self._qfrc[self.vadr].copy() if self._ident else self._E.T @ self._qfrc

    def advance(self, tau: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Step MuJoCo over one period with ``tau`` held; return new ``(q, dq)`` at ``t + Ts``.

        The applied generalized force of step s is :math:`\\tau + d(t_s, q_s, \\dot q_s)`.
        Time-only terms (the pulses) are tabulated for the whole period in one call each
        and the steps run in a tight loop (one ``mj_step`` per step); without any
        disturbance the period is one ``mj_step(model, data, nstep)`` call; any other
        disturbance is called at every step with the state MuJoCo has reached.
        """
        tau = held_torque(self, tau)
        m, d, step = self.model, self.data, self._mj.mj_step
        S, v = self.substeps, self.vadr
        qfrc = d.qfrc_applied
        pulses = self._pulses
        if pulses is not None and not pulses:  # torque only: one call for the period
            if self._ident:
                qfrc[:] = tau
            else:
                qfrc[v] = tau
            step(m, d, S)
        elif pulses is not None:
            times = self.t + self._offsets
            applied = np.add(tau, pulses[0].sample_times(times))
            for term in pulses[1:]:
                applied += term.sample_times(times)
            if self._ident:
                for row in applied:
                    qfrc[:] = row
                    step(m, d)
            else:
                for row in applied:
                    qfrc[v] = row
                    step(m, d)
        else:
            dist, qadr, h, t = self.disturbance, self.qadr, self.h, self.t
            for s in range(S):
                qfrc[v] = tau + dist(t + s * h, d.qpos[qadr], d.qvel[v])
                step(m, d)
        self.k += 1
        self.t = self.t0 + self.Ts * self.k
        self.q, self.dq = d.qpos[self.qadr], d.qvel[v]  # fancy indexing: new arrays
        if self._ident:
            self.engine_force = d.qfrc_constraint + d.qfrc_passive
        else:  # (a mimic equality's forces cancel in Eᵀ)
            self.engine_force = self._E.T @ (d.qfrc_constraint + d.qfrc_passive)
        self.contact_force = self.generalized_contact_force() if d.ncon else self._zero
        if self._contacts:
            self.history.append(self.contact_force)
        return self.q, self.dq


PLANTS[MuJoCoPlant.name] = MuJoCoPlant
