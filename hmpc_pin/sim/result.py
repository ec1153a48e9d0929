"""The result of a closed-loop run: arrays sampled at the control instants, saved as ``.npz``."""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import OutputError

__all__ = ["RESULT_ARRAYS", "Result"]

#: Arrays stored in a :class:`Result`, each of shape (K+1, n) except ``t`` (K+1,).
RESULT_ARRAYS = ("t", "q", "dq", "tau", "d", "d_hat", "q_ref", "dq_ref")


@dataclass
class Result:
    """Trajectories of a closed-loop run, sampled at the control instants.

    Attributes:
        t: Time [s], shape (K+1,).
        q, dq: Joint positions [rad] and velocities [rad/s], shape (K+1, n).
        tau: Torque computed at each instant and held over the next period [N·m].
        d: True disturbance :math:`d(t_k, q_k, \\dot q_k)` [N·m].
        d_hat: Observer estimate :math:`\\hat d_k` [N·m] (zeros without observer).
        q_ref, dq_ref: Reference at :math:`t_k` [rad, rad/s].
        joint_names: Names of the joints.
        complete: ``False`` when the run stopped early; ``message`` says why.
        meta: Free-form metadata (config name, settings), saved as JSON.
        extra: Further arrays by name, each (K+1, n) (e.g. ``contact_force``, MuJoCo's
            generalized contact force [N·m]), saved as ``extra_<name>``.
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

    @property
    def error(self) -> np.ndarray:
        """Tracking error :math:`q - r` [rad], shape (K+1, n)."""
        return self.q - self.q_ref

    @property
    def observer_error(self) -> np.ndarray:
        """Observer error :math:`w = d - \\hat d` (Eq 14) [N·m]."""
        return self.d - self.d_hat

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
        }
        part = path.with_name(path.name + ".part")
        try:
            if not path.parent.is_dir():
                raise OutputError(path.parent, "no such directory")
            with zipfile.ZipFile(part, "w", compression=zipfile.ZIP_STORED) as zf:
                for name, arr in arrays.items():
                    info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                    with zf.open(info, "w", force_zip64=True) as f:
                        np.lib.format.write_array(f, np.asanyarray(arr), allow_pickle=False)
            os.replace(part, path)
        except OSError as exc:
            raise OutputError(path.parent, exc.strerror or str(exc)) from exc
        finally:
            if part.exists():
                part.unlink()
        return path

    @classmethod
    def load(cls, path: str | Path) -> Result:
        """Read a result written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as f:
            return cls(
                **{name: f[name] for name in RESULT_ARRAYS},
                joint_names=tuple(str(s) for s in f["joint_names"]),
                complete=bool(f["complete"]),
                message=str(f["message"]),
                meta=json.loads(str(f["meta"])),
                extra={k[len("extra_") :]: f[k] for k in f.files if k.startswith("extra_")},
            )
