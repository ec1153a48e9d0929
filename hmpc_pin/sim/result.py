"""The result of a closed-loop run: arrays sampled at the control instants, saved as ``.npz``."""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import OutputError

__all__ = ["RESULT_ARRAYS", "TASK_ARRAYS", "Result"]

#: Arrays stored in a :class:`Result`, each of shape (K+1, n) except ``t`` (K+1,).
RESULT_ARRAYS = ("t", "q", "dq", "tau", "d", "d_hat", "q_ref", "dq_ref", "tau_applied")
#: Task-space arrays of an end-effector task (``None`` for a joint-space reference): the
#: frame's position [m] (K+1, 3) and unit quaternion (K+1, 4), order (x, y, z, w), scalar
#: last, measured (forward kinematics of q) and reference (the target path).
TASK_ARRAYS = ("ee_pos", "ee_pos_ref", "ee_quat", "ee_quat_ref")


@dataclass
class Result:
    """Trajectories of a closed-loop run, sampled at the control instants.

    Attributes:
        t: Time [s], shape (K+1,).
        q, dq: Joint positions [rad] and velocities [rad/s], shape (K+1, n).
        tau: Torque commanded by the controller at each instant [N·m] (without
            :math:`G(q)` when the arm adds it: :attr:`gravity_by_arm`).
        tau_applied: Torque the plant applied over the next period: ``tau`` clipped to
            the effort limit, :math:`\\mathrm{clip}(\\tau, -\\tau_{\\max}, \\tau_{\\max})`
            [N·m] (equal to ``tau`` without limits; NaN where nothing was applied). Files
            written before 0.3 have no record of it: it is ``tau`` when no period
            saturated and NaN otherwise.
        d: True disturbance [N·m] the plant applied at :math:`t_k`, the start of the
            period :math:`[t_k, t_k + T_s)`: :math:`d(t_k, q_k, \\dot q_k)`, but for a
            joint at rest with a Coulomb term of the disturbance (RK4 plant,
            ``coulomb = "stick-slip"``), where it is that term's value under the period's
            torque: the holding torque :math:`\\phi_i` that keeps the stuck joints'
            :math:`\\ddot q_S = 0` (:math:`G(q) - \\tau` for an arm held at rest without
            friction of its own), its share
            :math:`b_i/(F_i + b_i)` with the joint's own friction :math:`F_i`, or
            :math:`-b_i s_i` when the joint breaks away with sign :math:`s_i`. The last
            sample, which starts no period, and other plants record
            :math:`d(t_k, q_k, \\dot q_k)` (:math:`\\mathrm{sgn}\\,0 = 0`).
        d_hat: Observer estimate :math:`\\hat d_k` [N·m] (zeros without observer).
        q_ref, dq_ref: Reference at :math:`t_k` [rad, rad/s].
        joint_names: Names of the joints.
        complete: ``False`` when the run stopped early; ``message`` says why.
        meta: Free-form metadata (config name, settings), saved as JSON.
        extra: Further arrays by name, each (K+1, n) (e.g. ``contact_force``, MuJoCo's
            generalized contact force [N·m]), saved as ``extra_<name>``.
        ee_pos, ee_pos_ref: Pose tasks only: the frame's position and its target [m],
            (K+1, 3); ``meta["task"]`` names the frame.
        ee_quat, ee_quat_ref: Pose tasks only: the frame's orientation and its target,
            unit quaternions (x, y, z, w) (scalar last), (K+1, 4).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    d: np.ndarray
    d_hat: np.ndarray
    q_ref: np.ndarray
    dq_ref: np.ndarray
    joint_names: tuple[str, ...] = ()
    complete: bool = True
    message: str = ""
    meta: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    tau_applied: np.ndarray | None = None
    ee_pos: np.ndarray | None = None
    ee_pos_ref: np.ndarray | None = None
    ee_quat: np.ndarray | None = None
    ee_quat_ref: np.ndarray | None = None

    def __post_init__(self):
        if self.tau_applied is None:
            self.tau_applied = np.array(self.tau, dtype=float, copy=True)

    @property
    def gravity_by_arm(self) -> bool:
        """Whether ``tau`` and ``tau_applied`` exclude gravity because the arm adds
        :math:`G(q)` itself: a run of ``hmpc-pin franka`` (the FCI's torque command,
        ``meta["gravity_by_arm"]``; files of earlier versions: ``meta["franka"]``) or of
        ``hmpc-pin ros`` with ``[ros] gravity = "arm"``. The torque on the joints was then
        :math:`\\tau + G(q)`."""
        meta = self.meta if isinstance(self.meta, dict) else {}
        if "gravity_by_arm" in meta:
            return bool(meta["gravity_by_arm"])
        ros = meta.get("ros")
        return "franka" in meta or (isinstance(ros, dict) and ros.get("gravity") == "arm")

    @property
    def error(self) -> np.ndarray:
        """Tracking error :math:`q - r` [rad], shape (K+1, n)."""
        return self.q - self.q_ref

    @property
    def observer_error(self) -> np.ndarray:
        """Observer error :math:`w = d - \\hat d` (Eq 14) [N·m]; with a friction model fed
        forward (``extra["friction_feedforward"]``, :math:`\\tau_f`) the observer
        estimates what the model leaves, and :math:`w = d + \\tau_f - \\hat d`."""
        ff = self.extra.get("friction_feedforward")
        return self.d - self.d_hat if ff is None else self.d + ff - self.d_hat

    def save(self, path: str | Path) -> Path:
        """Write the arrays, joint names, completeness flag and metadata to ``.npz``.

        The file is byte-for-byte reproducible (fixed zip timestamps, sorted JSON), so
        the same run saves the same bytes, and it is written to ``<path>.part`` first
        and renamed: no half-written file is ever left under the final name.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        arrays = {
            **{name: getattr(self, name) for name in RESULT_ARRAYS},
            "joint_names": np.array(self.joint_names, dtype=str),
            "complete": np.array(self.complete),
            "message": np.array(self.message),
            "meta": np.array(json.dumps(self.meta, sort_keys=True)),
            **{f"extra_{name}": np.asarray(arr) for name, arr in sorted(self.extra.items())},
            **{n: getattr(self, n) for n in TASK_ARRAYS if getattr(self, n) is not None},
        }
        part = path.with_name(path.name + ".part")
        try:
            if not path.parent.is_dir():
                raise OutputError(path.parent, "is not writable (no such directory)", None)
            with zipfile.ZipFile(part, "w", compression=zipfile.ZIP_STORED) as zf:
                for name, arr in arrays.items():
                    info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                    with zf.open(info, "w", force_zip64=True) as f:
                        np.lib.format.write_array(f, np.asanyarray(arr), allow_pickle=False)
            os.replace(part, path)
        except OSError as exc:
            raise OutputError(
                path.parent, f"is not writable ({exc.strerror or exc})", None
            ) from exc
        finally:
            if part.exists():
                part.unlink()
        return path

    @classmethod
    def load(cls, path: str | Path) -> Result:
        """Read a result written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as f:
            meta = json.loads(str(f["meta"]))
            arrays = {name: f[name] for name in RESULT_ARRAYS if name in f.files}
        if "tau_applied" not in arrays:  # written before 0.3: known only without saturation
            saturated = any((meta.get("saturation") or {}).get("steps", ()))
            tau = arrays["tau"]
            arrays["tau_applied"] = np.full_like(tau, np.nan) if saturated else tau.copy()
        with np.load(path, allow_pickle=False) as f:
            return cls(
                **arrays,
                joint_names=tuple(str(s) for s in f["joint_names"]),
                complete=bool(f["complete"]),
                message=str(f["message"]),
                meta=meta,
                extra={k[len("extra_") :]: f[k] for k in f.files if k.startswith("extra_")},
                **{name: f[name] for name in TASK_ARRAYS if name in f.files},
            )
