"""Where a controller step's instructions go: steps planar3 or Panda for callgrind.

The floor benchmark's controller and states (``benchmarks.floor``: Nc = 1, the recorded
closed loop of ``benchmarks._fixtures.record_trajectory``), 200 untimed warm-up steps, then
``steps`` steps through ``ctrl.step`` between two calls of ``os.getppid``: with callgrind's
``--dump-before=getppid`` the second dump (``<out>.2``) holds those steps alone, the loop
around them included (a few thousand instructions per step, what any Python caller pays).
Instruction counts do not depend on the machine's load. Run, from the repository root::

    valgrind --tool=callgrind --dump-before=getppid --callgrind-out-file=/tmp/cg.out \\
        python benchmarks/tools/step_callgrind.py panda 400
    callgrind_annotate --inclusive=yes /tmp/cg.out.2

(``python``: the interpreter itself, not a virtual environment's symbolic link to it, with
the environment's site-packages on ``PYTHONPATH`` if valgrind writes no profile; the
compiled core as built is stripped: relink it without ``strip`` to see its functions.)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import hmpc_pin  # noqa: E402
from benchmarks._fixtures import HOMES, PANDA_LOCKED, load_arm, record_trajectory  # noqa: E402

WARMUP = 200


def main(argv: list[str] | None = None) -> int:
    """``step_callgrind.py ARM STEPS``: ARM planar3 or panda."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or args[0] not in ("planar3", "panda") or not args[1].isdigit():
        print("usage: step_callgrind.py {planar3,panda} STEPS", file=sys.stderr)
        return 2
    name, steps = args[0], int(args[1])
    if name == "planar3":
        arm = load_arm("planar3", ROOT / "robots" / "planar3.urdf", HOMES["planar3"], "chen")
    else:
        arm = load_arm("panda", "panda", HOMES["panda"], "general", PANDA_LOCKED)
    traj = record_trajectory(arm, WARMUP + steps)
    ctrl = hmpc_pin.make_controller(arm.robot, arm.config(1))
    ref = arm.reference()
    states = [(float(traj.t[i]), traj.q[i].copy(), traj.dq[i].copy()) for i in range(len(traj.t))]
    ctrl.reset(traj.q[0], traj.dq[0])
    for t, q, dq in states[:WARMUP]:
        ctrl.step(t, q, dq, ref)
    step, timed = ctrl.step, states[WARMUP : WARMUP + steps]
    os.getppid()  # callgrind --dump-before=getppid: the steps alone between two dumps
    for t, q, dq in timed:
        step(t, q, dq, ref)
    os.getppid()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
