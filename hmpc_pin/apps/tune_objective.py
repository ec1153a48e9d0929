"""What ``hmpc-pin tune`` minimises (:mod:`hmpc_pin.apps.tune`): a trial's sweep rows
scored as

.. math::

    J = p_{95}\\big(\\max_i \\mathrm{RMS}_i\\big)\\,\\Big(1 + w_s\\,\\bar s +
    w_{tv}\\,\\max\\big(0, \\overline{TV}/\\overline{TV}_0 - 1\\big)\\Big)

(:func:`objective_value`; each run by :func:`run_score`), with the weights
:data:`SATURATION_WEIGHT` :math:`w_s` and :data:`TV_WEIGHT` :math:`w_{tv}`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SATURATION_WEIGHT", "TV_WEIGHT", "objective_value", "run_score"]


#: Weight :math:`w_s` of the saturated fraction of the periods [-] (module docstring).
SATURATION_WEIGHT = 1.0
#: Weight :math:`w_{tv}` of the torque's total variation above the config's own [-].
TV_WEIGHT = 0.1


def run_score(row: dict, error_bound: float, duration: float | None) -> float:
    """One run's score [rad]: its worst joint's RMS error :math:`e` when bounded;
    otherwise :math:`\\bar e\\,(1 + \\ell) + \\min(e, 10\\bar e)` with :math:`\\bar e` the
    error bound and :math:`\\ell` the fraction of the run it did not finish, so that any
    bounded run ranks before any unbounded one, a later failure before an earlier one,
    and a smaller error before a larger one."""
    rms = float(row["rms_max"])
    if row["bounded"] and np.isfinite(rms):
        return rms
    lost = 1.0 - row["t_end"] / duration if duration and "t_end" in row else 0.0
    rms = min(rms, 10 * error_bound) if np.isfinite(rms) else 10 * error_bound
    return error_bound * (1.0 + min(max(lost, 0.0), 1.0)) + rms


def objective_value(
    rows: list[dict],
    error_bound: float,
    tv0: float | None,
    saturation_weight: float = SATURATION_WEIGHT,
    tv_weight: float = TV_WEIGHT,
    duration: float | None = None,
) -> tuple[float, dict]:
    """:math:`J` of a trial's sweep rows (module docstring, each run scored by
    :func:`run_score`) and its parts."""
    rms = np.array([run_score(r, error_bound, duration) for r in rows])
    p95 = float(np.quantile(rms, 0.95, method="inverted_cdf"))
    sat = float(np.mean([r["saturation"] for r in rows]))
    tv = float(np.mean([r["torque_tv"] for r in rows]))
    excess = max(0.0, tv / tv0 - 1.0) if tv0 else 0.0
    value = p95 * (1.0 + saturation_weight * sat + tv_weight * excess)
    return value, {
        "p95_rms": p95,
        "saturation": sat,
        "torque_tv": tv,
        "bounded": float(np.mean([r["bounded"] for r in rows])),
    }
