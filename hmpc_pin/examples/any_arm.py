"""Any arm in a few lines: write a starting config with ``init``, load it, run it.

For a URDF path or an example-robot-data name (``kinova``, ``talos_arm``, ``so101``, ...),
:func:`hmpc_pin.experiment.init.write_config` writes a commented TOML experiment (sine
around the reference posture inside the limits, inertia-scaled disturbances, an observer
valid for the arm, grippers locked: README, "Any arm"); the experiment is then built and
run, and the worst joint's RMS tracking error after 1 s is printed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from hmpc_pin.experiment.build import Experiment
from hmpc_pin.experiment.config import load_config
from hmpc_pin.experiment.init import write_config


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("robot", nargs="?", default="kinova", help="URDF path or robot name")
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory")
    parser.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    args = parser.parse_args(argv)
    path = write_config(args.robot, args.out / "any_arm.toml", args.duration, overwrite=True)
    experiment = Experiment.from_config(load_config(path))
    result = experiment.run()
    after = result.t >= 1.0
    rms = np.sqrt(np.mean(result.error[after] ** 2, axis=0))
    worst = int(rms.argmax())
    print(f"{path}: {experiment.robot.nq} joints, {experiment.config.controller.label}, "
          f"Ts = {experiment.config.controller.Ts:g} s")  # fmt: skip
    print(f"worst RMS after 1 s: {rms[worst]:.2e} ({result.joint_names[worst]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
