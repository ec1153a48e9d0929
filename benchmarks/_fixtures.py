"""Shared fixtures of the benchmark programs: the arms, their references and recorded states,
and a ProxSuite QP with the package's solver settings (for the Python floors).

Every benchmark imports what it shares from here, never from another benchmark program, so
that the programs form no import cycle (``tests/test_architecture.py``).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from proxsuite import proxqp

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from hmpc_pin.compensation.registry import compensation_names  # noqa: E402
from hmpc_pin.mpc.condensed import solver_settings  # noqa: E402

PANDA_LOCKED = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
#: Home poses [rad], each ± the sine amplitude inside the joint limits (checked at run time).
HOMES = {
    "planar3": (0.0, 0.0, 0.0),
    "ur5": (0.0, -1.2, 1.4, -1.0, -1.57, 0.0),
    "panda": (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785),
}
AMPLITUDE = 0.3  # [rad]
FREQUENCY = 0.1  # [Hz]
GRAVITY = 9.8  # [m/s²]


def log(message: str) -> None:
    """Progress on stderr (the report goes to stdout or a file)."""
    print(message, file=sys.stderr, flush=True)


#: The fields of the compiled core's ``QPSettings`` (ProxSuite ``Settings`` attributes).
QP_SETTINGS = (
    "eps_abs",
    "eps_rel",
    "eps_duality_gap_abs",
    "eps_duality_gap_rel",
    "eps_primal_inf",
    "eps_dual_inf",
    "max_iter",
    "verbose",
    "check_duality_gap",
)


def new_qp(nvar: int, n_in: int, eps_abs: float, max_iter: int, warm: bool = True,
           settings=None):  # fmt: skip
    """A dense ProxSuite QP (Python API) with the package's settings
    (:func:`hmpc_pin.mpc.condensed.solver_settings`, or ``settings``), set before ``init``."""
    qp = proxqp.dense.QP(nvar, 0, n_in, True)
    if settings is None:
        settings = solver_settings(eps_abs, max_iter, warm)
    for key in QP_SETTINGS:
        setattr(qp.settings, key, getattr(settings, key))
    qp.settings.initial_guess = getattr(proxqp.InitialGuess, settings.initial_guess.name)
    return qp


def observer_kinds() -> tuple[str, ...]:
    """The observer kinds this ``hmpc_pin`` offers (its compensation registry's observers)."""
    return compensation_names(table="observer")


def spatial_observer_kind() -> str:
    """The NDO design for spatial arms: Y = I (``"general"``)."""
    return "general"


@dataclass
class Arm:
    """A robot with its benchmark reference.

    Attributes:
        name: Label in the report. robot: The loaded robot.
        home: Sine offset [rad], shape (n,). observer: NDO kind.
    """

    name: str
    robot: hmpc_pin.Robot
    home: np.ndarray
    observer: str

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.robot.nq

    def reference(self) -> hmpc_pin.SineReference:
        """The benchmark reference: ``AMPLITUDE`` at ``FREQUENCY`` around ``home``."""
        return hmpc_pin.SineReference(
            self.n, amplitude=AMPLITUDE, frequency=FREQUENCY, offset=self.home
        )

    def config(self, Nc: int) -> hmpc_pin.ControllerConfig:
        """The paper's controller with control horizon ``Nc`` and this arm's observer."""
        observer = hmpc_pin.ObserverConfig(kind=self.observer)
        return hmpc_pin.ControllerConfig(Nc=Nc, observer=observer)


def load_arm(
    name: str,
    source: str | Path,
    home: tuple[float, ...] | np.ndarray,
    observer: str,
    locked: dict[str, float] | None = None,
) -> Arm:
    """Load an arm and check that ``home`` ± ``AMPLITUDE`` is inside its joint limits.

    Args:
        name: Label in the report.
        source: URDF path or example-robot-data name (:func:`hmpc_pin.load_robot`).
        home: Sine offset [rad], shape (n,).
        observer: NDO kind for :class:`hmpc_pin.ObserverConfig`.
        locked: Joints removed from the model, with their positions [rad or m].
    """
    robot = hmpc_pin.load_robot(source, gravity=GRAVITY, locked_joints=locked)
    home = np.asarray(home, dtype=float)
    if home.shape != (robot.nq,):
        raise ValueError(f"{name}: home pose has {home.size} entries, robot has {robot.nq}")
    bad = (home - AMPLITUDE <= robot.lower) | (home + AMPLITUDE >= robot.upper)
    if bad.any():
        raise ValueError(f"{name}: home ± {AMPLITUDE} rad leaves the limits on joints {bad}")
    return Arm(name, robot, home, observer)


@dataclass
class Trajectory:
    """States at the control instants [s, rad, rad/s] to replay through ``step``.

    Attributes:
        source: ``"closed loop"`` or ``"reference"`` (if the closed-loop run failed).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    source: str


def record_trajectory(arm: Arm, steps: int) -> Trajectory:
    """States along a closed-loop run of the hierarchical MPC (Nc = 1) on ``arm``.

    The run starts on the reference at rest, without disturbance, 1 ms RK4 plant. If
    it fails, the reference itself is returned (and labelled so).
    """
    ref = arm.reference()
    ctrl = hmpc_pin.make_controller(arm.robot, arm.config(1))
    q0 = ref.sample(0.0)[0]
    try:
        res = hmpc_pin.simulate(
            arm.robot, ctrl, ref, None, duration=(steps - 1) * ctrl.Ts, q0=q0, dq0=np.zeros(arm.n)
        )
        return Trajectory(res.t, res.q, res.dq, "closed loop")
    except hmpc_pin.SimulationError as exc:
        log(f"  {arm.name}: closed-loop recording failed ({exc}); replaying the reference")
    t = ctrl.Ts * np.arange(steps)
    q, dq = ref.sample_many(t)
    return Trajectory(t, q, dq, "reference")


PAPER_CONFIG = ROOT / "configs" / "paper_combined.toml"
CHAIN_SIZES = (2, 3, 6, 7, 12)
MiB = 2**20


@dataclass(frozen=True)
class Settings:
    """Sizes of the runs (full or ``--quick``).

    Attributes:
        warmup: Untimed controller steps before the timed ones.
        steps: Timed controller steps per case.
        sim_repeats: Repetitions of the 10 s simulation (wall-time median over them).
        soak_duration: Simulated time of the memory soak [s].
        soak_every: RSS sampling period of the soak, simulated [s].
        compare_duration: Simulated time of each comparison run on planar3 [s].
        compare_panda_duration: The same on Panda [s] (0 skips Panda).
        crocoddyl_iterations: Crocoddyl's (Box-)FDDP iteration budget per step.
        peer_blocks: Alternating blocks of the peers' comparison (``benchmarks/peers.py``).
        peer_scale: Its sequences' length, as a fraction of the full ones.
        peer_duration: Simulated time of the closed loop whose states the Crocoddyl
            step comparison replays [s].
    """

    warmup: int = 200
    steps: int = 2000
    sim_repeats: int = 5
    soak_duration: float = 600.0
    soak_every: float = 60.0
    compare_duration: float = 10.0
    compare_panda_duration: float = 10.0
    crocoddyl_iterations: int = 3
    floor_blocks: int = 8
    floor_steps: int = 800
    ratio_blocks: int = 6
    ratio_steps: int = 600
    long_steps: int = 300
    peer_blocks: int = 5
    peer_scale: float = 1.0
    peer_duration: float = 2.0


QUICK = Settings(
    warmup=20,
    steps=200,
    sim_repeats=1,
    soak_duration=30.0,
    soak_every=10.0,
    compare_duration=2.0,
    compare_panda_duration=2.0,
    floor_blocks=2,
    floor_steps=100,
    ratio_blocks=2,
    ratio_steps=100,
    long_steps=40,
    peer_blocks=2,
    peer_scale=0.25,
    peer_duration=0.5,
)
