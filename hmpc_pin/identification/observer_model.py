"""The observer that ran, as a model: its error dynamics and its discretisation, rebuilt
from the object that ran or from a run's record.

:func:`~hmpc_pin.identification.friction.fit_friction` passes its regressors through it
(so that the observer's lag is no bias) and leaves out the samples it needs to settle
(:meth:`ObserverModel.time_constant`); ``hmpc-pin check`` predicts the error its lag leaves
(:func:`~hmpc_pin.experiment.observer_analysis.observer_lag_error`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..compensation.registry import compensation_names, compensation_spec
from ..controllers.hierarchical import MODEL_AT, MPCSettings
from ..exceptions import ConfigError

if TYPE_CHECKING:
    from ..model.robot import Robot

__all__ = ["ObserverModel"]


@dataclass(frozen=True)
class ObserverModel:
    """The observer whose estimate is fitted: its error dynamics
    :math:`\\dot{\\hat d} = L(q)\\,(d - \\hat d)` (exact for any :math:`d`,
    :mod:`hmpc_pin.compensation.observers`), with :math:`L = cY\\,M(q)^{-1}` (the NDO of
    Eq 13/30: ``"chen"``, ``"general"``, or any matrix :math:`cY`, e.g. of a bandwidth)
    or :math:`L = \\mathrm{diag}(K_O)` (``"momentum"``), discretised as the observer is.

    Attributes:
        kind: ``"chen"``, ``"general"`` or ``"momentum"``.
        gain: :math:`c` [1/s·(kg·m²)] (``matrix`` unset) or :math:`K_O` [1/s], one value or
            one per joint (momentum).
        Ts: The control period [s].
        robot: The arm's :class:`~hmpc_pin.model.robot.Robot` (for :math:`M(q)`).
        implicit: Backward (``True``) or forward Euler (the NDO; the momentum observer is
            always semi-implicit).
        matrix: The NDO's :math:`cY` itself, (n, n) (overrides ``gain`` × the kind's
            :math:`Y`): what a bandwidth observer runs with.
        model_at: ``"end"``: :math:`M` at the period's end state :math:`q_k`;
            ``"start"``: at :math:`q_{k-1}` (``[controller.observer] model_at``).
    """

    kind: str
    gain: float | np.ndarray
    Ts: float
    robot: Robot | None = None
    implicit: bool = True
    matrix: np.ndarray | None = None
    model_at: str = MPCSettings.model_at

    @classmethod
    def of(
        cls, compensation, robot=None, model_at: str = MPCSettings.model_at
    ) -> ObserverModel | None:
        """The model of a built observer (the object that runs, not its config), or
        ``None`` when ``compensation`` is no observer. A feedback gate
        (:class:`~hmpc_pin.compensation.gate.FeedbackGate`) is looked through."""
        from ..compensation.observers import DisturbanceObserver, MomentumObserver

        while hasattr(compensation, "inner"):
            compensation = compensation.inner
        if isinstance(compensation, DisturbanceObserver):
            return cls(
                "general",
                1.0,
                compensation.Ts,
                robot,
                compensation.discretization == "implicit",
                np.array(compensation.cY, dtype=float),
                model_at,
            )
        if isinstance(compensation, MomentumObserver):
            return cls(
                "momentum",
                np.array(compensation.K, dtype=float),
                compensation.Ts,
                robot,
                True,
                None,
                model_at,
            )
        return None

    def record(self) -> dict:
        """The JSON record a run keeps in ``meta["observer_model"]`` (:meth:`from_record`
        reads it back)."""
        out: dict = {
            "kind": self.kind,
            "Ts": float(self.Ts),
            "model_at": self.model_at,
            "discretization": "implicit" if self.implicit else "explicit",
        }
        if self.matrix is not None:
            out["matrix"] = np.asarray(self.matrix, dtype=float).tolist()
        else:
            out["gain"] = np.asarray(self.gain, dtype=float).tolist()
        return out

    @classmethod
    def from_record(cls, record, robot=None, n: int | None = None) -> ObserverModel:
        """The model of a run's ``meta["observer_model"]``: this version's record (the
        matrix :math:`cY` or :math:`K_O` that ran) or an older one (kind and gain).

        Raises:
            ConfigError: (key ``"observer_model"``) the record is not one of these; the
                message says what is missing.
        """

        def bad(what: str) -> ConfigError:
            return ConfigError(
                "observer_model", f"the run's observer record {what}; use --source dynamics"
            )

        if not isinstance(record, dict):
            raise bad(f"is {type(record).__name__}, expected a table")
        kind, period = record.get("kind"), record.get("Ts")
        kinds = compensation_names(table="observer")
        if kind not in kinds:
            raise bad(f"names the kind {kind!r}, expected one of {kinds}")
        try:  # a JSON number (or its text); anything else is no period
            if not isinstance(period, (int, float, str)):
                raise TypeError
            Ts = float(period)
        except (TypeError, ValueError):
            raise bad(f"has the period Ts = {period!r}, expected a number [s]") from None
        if not (np.isfinite(Ts) and Ts > 0):
            raise bad(f"has the period Ts = {Ts!r}, expected > 0 [s]")
        implicit = record.get("discretization", "implicit") == "implicit"
        model_at = record.get("model_at", "end")  # records without it ran at the end
        if model_at not in MODEL_AT:
            raise bad(f"has model_at = {model_at!r}, expected one of {MODEL_AT}")
        if record.get("matrix") is not None:
            M = np.asarray(record["matrix"], dtype=float)
            if (
                M.ndim != 2
                or M.shape[0] != M.shape[1]
                or (n is not None and M.shape[0] != n)
                or not np.all(np.isfinite(M))
            ):
                raise bad(
                    f"has an observer matrix of shape {M.shape}, expected a finite "
                    f"({n or 'n'}, {n or 'n'}) matrix"
                )
            return cls(kind, 1.0, Ts, robot, implicit, M, model_at)
        gain = record.get("gain")
        try:
            g = np.asarray(gain, dtype=float)
        except (TypeError, ValueError):
            g = np.array(np.nan)
        if gain is None or g.ndim > 1 or not np.all(np.isfinite(g)) or not np.all(g > 0):
            raise bad(
                f"has no observer matrix and the gain {gain!r} (a bandwidth observer "
                "recorded by an older version); run it again to record the observer "
                "that ran"
            )
        if g.ndim == 1 and compensation_spec(kind).Y is not None:
            raise bad(f"has a per-joint gain for the {kind!r} observer, expected one value")
        return cls(kind, g if g.ndim else float(g), Ts, robot, implicit, None, model_at)

    def _mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """:math:`M(q)` of the arm, which the NDO's :math:`L = cY M(q)^{-1}` needs."""
        if self.robot is None:
            raise ConfigError(
                "robot",
                f"the {self.kind!r} observer's L = cY M(q)^-1 needs the arm's model; "
                "pass robot= (the Robot that ran)",
            )
        return self.robot.mass_matrix(q)

    def time_constant(self, q: np.ndarray, samples: int = 200) -> float:
        """The slowest time constant of the observer's error over the configurations
        ``q`` (K, n) it ran at [s]: :math:`\\tau = -T_s / \\ln \\rho`, with :math:`\\rho` the
        largest spectral radius of its one-period error map, :math:`(I + T_sL)^{-1}`
        (backward Euler; the momentum observer) or :math:`I - T_sL` (forward Euler),
        over up to ``samples`` configurations evenly spread along ``q``. ``inf`` when the
        map does not contract.
        """
        n = q.shape[1]
        Y = compensation_spec(self.kind).Y
        if Y is None:  # L = diag(K_O), configuration-free
            maps = [1.0 / (1.0 + self.Ts * np.broadcast_to(np.asarray(self.gain, float), (n,)))]
        else:
            cY = np.asarray(self.matrix if self.matrix is not None else self.gain * Y(n), float)
            maps = []
            for k in np.unique(np.linspace(0, len(q) - 1, min(samples, len(q))).astype(int)):
                L = self.Ts * cY @ np.linalg.inv(self._mass_matrix(q[k]))
                step = np.linalg.inv(np.eye(n) + L) if self.implicit else np.eye(n) - L
                maps.append(np.linalg.eigvals(step))
        rho = max(float(np.max(np.abs(m))) for m in maps)
        return float(-self.Ts / np.log(rho)) if rho < 1 else float("inf")

    def coupled(self) -> bool:
        """Whether one joint's disturbance enters the other joints' estimates (the NDO's
        :math:`L = cY M^{-1}`; the momentum observer's :math:`L` is diagonal)."""
        return compensation_spec(self.kind).Y is not None

    def filter(self, q: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """The observer's response :math:`g` to the disturbance signals ``phi``,
        (K, n, p) for K instants, n joints and p signals, started at rest.

        Backward Euler: :math:`(I + T_sL_k)\\,g_k = g_{k-1} + T_sL_k\\,\\varphi_k`.
        """
        K, n, p = phi.shape
        g = np.zeros_like(phi)
        Y = compensation_spec(self.kind).Y  # None: L = diag(K_O) (the momentum observer)
        if Y is None:
            a = self.Ts * np.broadcast_to(np.asarray(self.gain, dtype=float), (n,))[:, None]
        elif self.matrix is not None:
            cY = np.asarray(self.matrix, dtype=float)
        else:
            cY = self.gain * Y(n)
        shift = 1 if self.model_at == "start" else 0
        prev = np.zeros((n, p))
        for k in range(1, K):
            if Y is None:
                prev = (prev + a * phi[k]) / (1 + a)
            else:
                M = self._mass_matrix(q[k - shift])
                L = self.Ts * cY @ np.linalg.inv(M)
                if self.implicit:
                    prev = np.linalg.solve(np.eye(n) + L, prev + L @ phi[k])
                else:
                    prev = prev + L @ (phi[k] - prev)
            g[k] = prev
        return g
