"""Nonlinear disturbance observer (NDO), Eq (6)–(18) and (28)–(30).

Continuous form (Eq 13), with the auxiliary state :math:`z = \\hat d - p`:

.. math::

    \\dot z = -L z + L\\,(C\\dot q + G - \\tau - p), \\qquad \\hat d = z + p,

where :math:`p(q,\\dot q) = c\\,Y\\dot q` and :math:`L(q) = c\\,Y M(q)^{-1}` so that
:math:`\\dot p = L M \\ddot q` (Eq 9). The estimation error :math:`w = d - \\hat d`
then obeys :math:`\\dot w = -L w` for a constant disturbance (Eq 18).

Two choices of :math:`Y` are offered:

* ``"chen"``: :math:`Y` is the lower-triangular matrix of ones (Eq 28–30), the
  paper's design, proven for planar serial arms.
* ``"general"``: :math:`Y = I` (:math:`p = c\\dot q`, :math:`L = cM^{-1}`), the
  general design of Mohammadi et al. (2013) with :math:`X = I/c`. Their Lyapunov
  condition :math:`X + X^T - X\\dot M X^T > 0` becomes
  :math:`c > \\tfrac12\\,\\sup\\|\\dot M(q,\\dot q)\\|_2` over the joint and velocity ranges,
  which :func:`general_gain_bound` evaluates with Pinocchio
  (:math:`\\dot M = C + C^T`); above that bound the error converges on any arm,
  planar or spatial. Planar arms keep the paper's ``"chen"`` by default.

A third estimator, :class:`MomentumObserver` (``kind = "momentum"``), is De Luca's
generalized-momentum observer (SPEC §2): no :math:`M^{-1}` and no acceleration,

.. math::

    r = K_O\\Big[M\\dot q - M_0\\dot q_0
        - \\int_0^t (\\tau + C^T\\dot q - G + r)\\,ds\\Big],
    \\qquad \\dot r = K_O (d - r),

i.e. one first-order filter per joint at rate :math:`K_O` [1/s], stable for any
:math:`K_O > 0` on any arm.

Discretisation (SPEC §2). At the control period :math:`T_s` the observer is
integrated with backward Euler, which is unconditionally stable for any gain:

.. math::

    (I + T_s L_k)\\,z_k = z_{k-1} + T_s L_k\\,(n_k - \\tau_{k-1} - p_k),

with :math:`n_k = C\\dot q + G` at the measured state and :math:`\\tau_{k-1}` the
torque held over the last period. Explicit (forward) Euler is available for
comparison only: it diverges once :math:`T_s c\\,\\lambda_{\\max}(Y M^{-1}) > 2`.

The NDO's update is the compiled core's (``cpp/src/observer.cpp``, :mod:`hmpc_pin.native`), the
same object the compiled control step advances; its numpy version is the test oracle
(``tests/reference/observers.py``).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..exceptions import ConfigError
from ..native import load as load_native

__all__ = [
    "DEFAULT_DESIGN",
    "DEFAULT_DISCRETIZATION",
    "DEFAULT_GAIN",
    "OBSERVER_KINDS",
    "DisturbanceObserver",
    "MomentumObserver",
    "default_observer",
    "general_gain_bound",
    "observer_matrix",
]

#: The observers' compensation names, kept for callers of 0.2: the compensation registry
#: (:mod:`hmpc_pin.compensation.registry`, which imports this module) is the source, and
#: ``compensation_names(table="observer")`` the names (a test checks that they agree).
OBSERVER_KINDS = ("chen", "general", "momentum")
DISCRETIZATIONS = ("implicit", "explicit")

#: The default observer, stated once: Chen's NDO (the design of Eq 28-30) ...
DEFAULT_DESIGN = "chen"
#: ... with the gain c = 100 (the paper does not give it; this project's choice) ...
DEFAULT_GAIN = 100.0
#: ... discretised by backward Euler (stable for any gain).
DEFAULT_DISCRETIZATION = "implicit"


def observer_matrix(kind: str, n: int) -> np.ndarray:
    """Return the constant matrix :math:`Y` of the observer design ``kind``.

    Args:
        kind: ``"chen"`` (lower-triangular ones, Eq 28) or ``"general"`` (identity).
        n: Number of joints.
    """
    if kind == "chen":
        return np.tril(np.ones((n, n)))
    if kind == "general":
        return np.eye(n)
    raise ConfigError("observer.kind", f"got {kind!r}; expected 'chen' or 'general'")


def default_observer(n: int, Ts: float) -> DisturbanceObserver:
    """The default observer (:data:`DEFAULT_DESIGN`, :data:`DEFAULT_GAIN`,
    :data:`DEFAULT_DISCRETIZATION`) of ``n`` joints at the control period ``Ts`` [s]."""
    return DisturbanceObserver(n, Ts, DEFAULT_GAIN, DEFAULT_DESIGN, DEFAULT_DISCRETIZATION)


class DisturbanceObserver:
    """Discrete-time NDO of Eq (13) with gain :math:`c` and design matrix :math:`Y`.

    Args:
        n: Number of joints.
        Ts: Sampling period [s].
        gain: Observer gain :math:`c` [1/s·(kg·m²)]; larger is faster.
        kind: ``"chen"`` or ``"general"`` (see module docstring).
        discretization: ``"implicit"`` (backward Euler, default) or ``"explicit"``.
        cY: The matrix :math:`cY` itself, (n, n), instead of ``gain`` × the ``kind``'s
            :math:`Y` (e.g. :func:`~hmpc_pin.compensation.bandwidth.observer_cY` of a
            bandwidth); ``gain`` is then ignored and ``kind`` must be ``"general"``.

    Attributes:
        estimate: The current disturbance estimate :math:`\\hat d` [N·m], shape (n,).
    """

    def __init__(
        self,
        n: int,
        Ts: float,
        gain: float,
        kind: str = "chen",
        discretization: str = "implicit",
        cY: np.ndarray | None = None,
    ):
        if discretization not in DISCRETIZATIONS:
            raise ConfigError(
                "discretization", f"got {discretization!r}; expected one of {DISCRETIZATIONS}"
            )
        self.n = n
        self.Ts = float(Ts)
        self.gain = float(gain)
        self.kind = kind
        self.discretization = discretization
        if cY is not None:
            cY = np.array(cY, dtype=float)
            if cY.shape != (n, n) or not np.all(np.isfinite(cY)) or kind != "general":
                raise ConfigError(
                    "cY",
                    f"expected a finite ({n}, {n}) matrix with kind 'general', got "
                    f"shape {cY.shape} with kind {kind!r}",
                )
            self.cY = cY
        else:
            self.cY = self.gain * observer_matrix(kind, n)
        self._compile()

    def _compile(self) -> None:
        """The compiled observer (``hmpc_pin._core.NDO``), which owns z and d̂: :attr:`z` and
        :attr:`estimate` are read-only views of its vectors."""
        self._core = load_native().NDO(self.cY, self.Ts, self.discretization == "implicit")
        self._z = self._core.z
        self._estimate = self._core.estimate

    @property
    def z(self) -> np.ndarray:
        """The observer state :math:`z = \\hat d - p` [N·m], shape (n,) (read-only view,
        updated in place)."""
        return self._z

    @property
    def estimate(self) -> np.ndarray:
        """The current estimate :math:`\\hat d` [N·m], shape (n,) (read-only view, updated
        in place by :meth:`update` and by the compiled control step)."""
        return self._estimate

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_core"]  # the compiled object is rebuilt on unpickling
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        z, estimate = state["_z"], state["_estimate"]  # copies of the pickled views
        self._compile()
        self._core.state = (z, estimate)

    def compiled_port(self) -> Any:
        """The compiled observer (``hmpc_pin._core.NDO``): the control step advances this very
        object in C++ (:meth:`update` is the same computation called from Python)."""
        return self._core

    def compiled_form(self) -> tuple:
        """Deprecated since 0.3: :meth:`compiled_port`; ``("ndo", the compiled observer)``."""
        warnings.warn(
            "compiled_form() is deprecated since 0.3; call compiled_port()",
            DeprecationWarning,
            stacklevel=2,
        )
        return ("ndo", self._core)

    def p(self, dq: np.ndarray) -> np.ndarray:
        """Auxiliary function :math:`p(\\dot q) = c Y \\dot q` (Eq 28)."""
        return self.cY @ dq

    def gain_matrix(self, M: np.ndarray) -> np.ndarray:
        """Observer gain :math:`L(q) = c Y M(q)^{-1}` (Eq 30)."""
        # L M = cY  <=>  M^T L^T = (cY)^T
        return np.linalg.solve(M.T, self.cY.T).T

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start at :math:`z_0 = -p(\\dot q_0)`, i.e. :math:`\\hat d(0) = 0` (``q0`` unused)."""
        self._core.reset(np.asarray(dq0, dtype=float))

    def update(
        self,
        M: np.ndarray,
        nle: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray,
        tau_prev: np.ndarray,
        v: np.ndarray | None = None,
    ) -> np.ndarray:
        """Advance one sampling period and return the new estimate :math:`\\hat d_k`
        (the :class:`~hmpc_pin.compensation.base.Compensation` protocol).

        Backward (implicit) or forward (explicit) Euler on Eq (13), each one linear solve
        with Eigen's partial-pivoting LU (module docstring; ``cpp/include/hmpc/observer.hpp``):
        :math:`(M + T_s cY)\\,w = n_k - \\tau_{k-1} - p_k - z` (explicit: :math:`M w = \\dots`),
        :math:`z \\leftarrow z + T_s cY w`, :math:`\\hat d_k = z + p_k`.

        Args:
            M: Inertia matrix at the measured state [kg·m²], (n, n).
            nle: :math:`C\\dot q + G` at the measured state [N·m], (n,).
            q: Measured joint position [rad] (unused here; the momentum observer needs it).
            dq: Measured joint velocity [rad/s], (n,).
            tau_prev: Torque applied over the period that just ended [N·m], (n,).
            v: Outer-loop acceleration of that period [rad/s²] (unused by the NDO).

        Returns:
            A copy of :attr:`estimate` [N·m], (n,).
        """
        self._core.update(M, nle, dq, tau_prev)
        return self._estimate.copy()


class MomentumObserver:
    """De Luca's generalized-momentum observer, discretised at the control period.

    With :math:`p = M\\dot q` and :math:`\\beta = \\tau + C^T\\dot q - G`, the integral
    :math:`I` and residual :math:`r` are advanced semi-implicitly (backward Euler on the
    :math:`r` term, unconditionally stable for any gain):

    .. math::

        (I + T_s K_O)\\, r_k = K_O\\,(p_k - p_0 - I_{k-1} - T_s \\beta_k), \\qquad
        I_k = I_{k-1} + T_s(\\beta_k + r_k),

    which gives :math:`r_k = (I + T_sK_O)^{-1}(r_{k-1} + K_O\\,\\Delta p_k - T_sK_O\\beta_k)`,
    so for a constant disturbance the error decays by :math:`1/(1 + T_s K_O)` per step.
    :math:`C^T\\dot q` comes from ``pin.computeCoriolisMatrix``, :math:`G = n - C\\dot q`.

    Args:
        robot: The controller's :class:`~hmpc_pin.model.robot.Robot` (for :math:`C`).
        Ts: Sampling period [s].
        gain: :math:`K_O` [1/s], scalar or per joint (n,), > 0.

    Attributes:
        estimate: The current disturbance estimate :math:`r_k` [N·m], shape (n,).
    """

    def __init__(self, robot, Ts: float, gain):
        self.robot = robot
        self.n = n = robot.nq
        self.Ts = float(Ts)
        self.K = np.broadcast_to(np.asarray(gain, dtype=float), (n,)).copy()
        self.gain = self.K
        self._den = 1.0 + self.Ts * self.K
        self.p0 = np.zeros(n)
        self.integral = np.zeros(n)
        self.estimate = np.zeros(n)

    def reset(self, q0: np.ndarray, dq0: np.ndarray) -> None:
        """Start at :math:`r = 0`; :math:`p_0 = M(q_0)\\dot q_0` (zero for a start at rest)."""
        dq0 = np.asarray(dq0, dtype=float)
        self.p0 = self.robot.mass_matrix(np.asarray(q0, dtype=float)) @ dq0
        self.integral = np.zeros(self.n)
        self.estimate = np.zeros(self.n)

    def update(
        self,
        M: np.ndarray,
        nle: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray,
        tau_prev: np.ndarray,
        v: np.ndarray | None = None,
    ) -> np.ndarray:
        """Advance one period with the measured ``q``, ``dq`` and ``τ_{k-1}`` (``v`` unused;
        the :class:`~hmpc_pin.compensation.base.Compensation` protocol)."""
        C = self.robot.coriolis_matrix(q, dq)
        Cdq = C @ dq
        beta = tau_prev + C.T @ dq - (nle - Cdq)
        p = M @ dq
        r = self.K * (p - self.p0 - self.integral - self.Ts * beta) / self._den
        self.integral += self.Ts * (beta + r)
        self.estimate = r
        return r


def general_gain_bound(robot, samples: int = 200, seed: int = 0, velocity=None) -> float:
    """Lower bound on the gain :math:`c` of the ``"general"`` NDO (Mohammadi et al. 2013).

    Returns :math:`\\tfrac12 \\max \\|\\dot M(q, \\dot q)\\|_2` over ``samples`` random
    configurations inside the joint limits (infinite limits clipped to ±π) and, at
    each, the velocity-limit vertices :math:`\\dot q_j = \\pm\\bar{\\dot q}_j` of a random sign
    pattern and its opposite, with :math:`\\dot M = C + C^T` from Pinocchio.
    The observer error converges for :math:`c` above it.

    Args:
        robot: The :class:`~hmpc_pin.model.robot.Robot`.
        samples: Number of random configurations.
        seed: Random seed.
        velocity: Velocity bounds [rad/s] (n,); default the robot's velocity limits.
    """
    rng = np.random.default_rng(seed)
    lo = np.clip(robot.lower, -np.pi, np.pi)
    hi = np.clip(robot.upper, -np.pi, np.pi)
    vmax = np.asarray(robot.velocity_limit if velocity is None else velocity, dtype=float)
    worst = 0.0
    for _ in range(samples):
        q = rng.uniform(lo, hi)
        sign = rng.choice([-1.0, 1.0], size=robot.nq)
        for dq in (sign * vmax, -sign * vmax):
            C = robot.coriolis_matrix(q, dq)
            worst = max(worst, 0.5 * float(np.linalg.norm(C + C.T, 2)))
    return worst
