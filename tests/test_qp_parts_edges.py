"""The joint QPs' parts at the edges their one-line bugs hid in (benchmarks/tools/mutants_cpp.py):
each against its numpy oracle (tests/reference/qp_parts.py) or the documented rule.

The parts' main tests are in test_qp_parts.py (this file reuses its problem and the KKT
solver's data).
"""

from __future__ import annotations

import numpy as np

from hmpc_pin.native import load as load_native
from tests.reference import qp_parts
from tests.test_qp_parts import EPS, _gradients, _mpc

core = load_native()


def test_box_active_set_answers_at_once_from_the_solutions_own_active_set():
    """iter = 0: one solve per guess and no exchange. From the last solution's active set,
    as it stands (the error persisting), the first solve is the minimiser: the shortcut must
    answer it, with the oracle's point, without an exchange."""
    mpc = _mpc()
    H = mpc.H
    part = core.BoxActiveSet(H)
    bound = 0
    for g in _gradients(mpc, 40, seed=9):
        u, z = qp_parts.box_qp(H, g, -1.0, 1.0)
        bound += int(np.any(z != 0.0))
        got = part.solve(g, -1.0, 1.0, u, 0, EPS)
        assert got is not None, "the exact active set was not answered without an exchange"
        np.testing.assert_allclose(got[0], u, atol=1e-8)
        np.testing.assert_allclose(got[1], z, atol=1e-8 * (1.0 + np.abs(g).max()))
    assert bound >= 30  # most gradients put some input at a bound
