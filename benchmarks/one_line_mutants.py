"""Kill rate of one-line mutations: apply each, run the tests that cover that code, revert.

A mutant is *killed* when its tests fail. The set covers the code of the reliability
checks (start-up guard, library validation, inertia check, moved configs, contact lines)
and the code whose one-line bugs an earlier suite missed (retiming, trajectory files,
pose IK, quaternions, MuJoCo mapping, collision watch, measurement model, init's speed
cap, the applied-torque clip). Run from the repository root:

    .venv/bin/python benchmarks/one_line_mutants.py [--only SUBSTRING]

Prints one line per mutant and the kill rate per group.
"""

# ruff: noqa: E501  (the mutants are one source line each)
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

IC = "tests/test_independent_checks.py"
LV = "tests/test_library_validation.py"
CHK = "tests/test_check.py"
IDF = "tests/test_identify.py"
IDN = "tests/test_identification.py"
TUN = "tests/test_tune.py"

#: (group, file, old line part, new line part, tests)
MUTANTS = [
    # ---- code of this round (reliability)
    ("new", "hmpc_pin/checks.py", 'if out["Nc"] > out["N"]:', 'if out["Nc"] >= out["N"]:', [LV]),
    ("new", "hmpc_pin/checks.py", "if np.any(lo >= hi):", "if np.any(lo > hi):", [LV]),
    ("new", "hmpc_pin/checks.py", "if positive and x <= 0:", "if positive and x < 0:", [LV]),
    ("new", "hmpc_pin/compensation/base.py", "if shape != (n,):", "if shape != (n,) and False:", [LV]),
    ("new", "hmpc_pin/compensation/base.py", "rel_tol=1e-9):", "rel_tol=1.0):", [LV]),
    ("new", "hmpc_pin/compensation/base.py", 'and not robot.is_planar_chain():',
     'and robot.is_planar_chain():', [LV]),
    ("new", "hmpc_pin/tasks/base.py", "and int(size) != n:", "and int(size) > n:", [LV]),
    ("new", "hmpc_pin/sim/plants.py", "    if not plant._was_reset:", "    if False:", [LV]),
    ("new", "hmpc_pin/sim/plants.py", "if tau.shape != (plant.n,):", "if tau.ndim != 1:", [LV]),
    ("new", "hmpc_pin/controllers/hierarchical.py", "        if not self._was_reset:",
     "        if self._was_reset is None:", [LV]),
    ("new", "hmpc_pin/model/robot.py", "if moments[0] < -1e-9 * scale:",
     "if moments[0] < -1e-3 * scale:", ["tests/test_inertias.py"]),
    ("new", "hmpc_pin/model/robot.py", "if moments[0] + moments[1] < moments[2]",
     "if moments[0] + moments[2] < moments[1]", ["tests/test_inertias.py"]),
    ("new", "hmpc_pin/model/robot.py", "movable = joint.get(\"type\") != \"fixed\"",
     "movable = True or joint.get(\"type\") != \"fixed\"", ["tests/test_inertias.py"]),
    ("new", "hmpc_pin/model/robot.py", "if not (math.isfinite(mass) and mass >= 0):",
     "if not math.isfinite(mass):", ["tests/test_inertias.py"]),
    ("new", "hmpc_pin/experiment/config/experiment.py",
     "resolved = given if given.is_absolute() else (base / given).resolve()",
     "resolved = given if given.is_absolute() else given.resolve()",
     ["tests/test_moved_configs.py"]),
    ("new", "hmpc_pin/experiment/config/experiment.py", "if _shipped_robot(given.stem):",
     "if _shipped_robot(given.name):", ["tests/test_moved_configs.py"]),
    ("new", "hmpc_pin/apps/metrics.py", "j = int(np.argmax(peak))", "j = 0",
     [IC + "::test_contact_lines_name_the_joint_of_the_peak_force_and_its_unit",
      "tests/test_cli_outputs.py::test_run_prints_the_first_contact_and_the_collision_flag"]),
    ("new", "hmpc_pin/_startup.py", "    signal.signal(signal.SIGINT, _interrupt)",
     "    pass", ["tests/test_interrupts.py::test_ctrl_c_while_the_figures_are_drawn_names_the_files_written"]),
    ("new", "hmpc_pin/apps/run.py", "        if not getattr(exc, \"files\", ()):",
     "        if getattr(exc, \"files\", ()):",
     ["tests/test_interrupts.py::test_ctrl_c_while_the_figures_are_drawn_names_the_files_written"]),
    # ---- code an earlier suite let one-line bugs through
    ("earlier", "hmpc_pin/controllers/base.py", "return np.clip(self.tau, effort[0], effort[1], out=effort[2])",
     "return self.tau", [IC]),
    ("earlier", "hmpc_pin/controllers/wrappers.py", "ratio = np.abs(self.gate.observed) / self.threshold",
     "ratio = self.gate.observed / self.threshold", [IC]),
    ("earlier", "hmpc_pin/controllers/wrappers.py", "self._hold = _Hold(q)", "self._hold = _Hold(q * 0)", [IC]),
    # (the measurement noise of MeasuredController moved to the compiled measurement port,
    # cpp/src/measurement.cpp: its two mutants need a rebuild each and left this list)
    ("earlier", "hmpc_pin/tasks/pose.py", "return -coeffs if coeffs[3] < 0 else coeffs",
     "return -coeffs if coeffs[3] > 0 else coeffs", [IC]),
    ("earlier", "hmpc_pin/tasks/pose.py", "return pin.Quaternion(w, x, y, z).toRotationMatrix()",
     "return pin.Quaternion(w, -x, -y, -z).toRotationMatrix()", [IC]),
    ("earlier", "hmpc_pin/tasks/pose.py", "if e_pos > position_tol or e_rot > orientation_tol:",
     "if e_pos > position_tol and e_rot > orientation_tol:", [IC]),
    ("earlier", "hmpc_pin/tasks/pose.py", "if e_pos > position_tol or e_rot > orientation_tol:",
     "if e_pos > position_tol:", [IC]),
    ("earlier", "hmpc_pin/tasks/trajectory.py", "tol = 0.25 * np.abs(step).max(axis=0) + 1e-6",
     "tol = 0.25 * np.abs(step).max() + 1e-6", [IC]),
    ("earlier", "hmpc_pin/tasks/waypoints.py", "lam = max(1.0, v_ratio / margin, np.sqrt(a_ratio / margin))",
     "lam = max(1.0, v_ratio / margin, a_ratio / margin)", [IC]),
    ("earlier", "hmpc_pin/tasks/waypoints.py", "lam = max(1.0, v_ratio / margin, np.sqrt(a_ratio / margin))",
     "lam = max(1.0, v_ratio / margin)", [IC]),
    ("earlier", "hmpc_pin/tasks/waypoints.py", "ts * lam + t_start, q, dq / lam, joint_names,",
     "(ts + t_start) * lam, q, dq / lam, joint_names,", [IC]),
    ("earlier", "hmpc_pin/tasks/waypoints.py", "ddq=ddq / lam**2", "ddq=ddq / lam", [IC]),
    ("earlier", "hmpc_pin/experiment/init.py", "speed_cap = np.where(vmax > 0, 0.5 * vmax / (2 * np.pi * amp), np.inf)",
     "speed_cap = np.where(vmax > 0, 0.5 * vmax / (np.pi * amp), np.inf)", [IC]),
    ("earlier", "hmpc_pin/experiment/init.py", "self.frequency = float(min(FREQUENCY, speed_cap.min()))",
     "self.frequency = float(min(FREQUENCY, speed_cap[0]))", [IC]),
    ("earlier", "hmpc_pin/sim/mujoco.py", "dofs = np.array([model.joint(name).dofadr[0] for name in robot.joint_names])",
     "dofs = np.arange(robot.nq)", [IC]),
    ("earlier", "hmpc_pin/sim/mujoco.py", "self.engine_force = d.qfrc_constraint + d.qfrc_passive",
     "self.engine_force = d.qfrc_constraint - d.qfrc_passive", [IC]),
    # ---- written after the tests were final (no test changed for them): an unbiased sample
    ("fresh", "hmpc_pin/checks.py", "if lo.shape != hi.shape and lo.ndim and hi.ndim:", "if False:", [LV, "tests/test_config.py"]),
    ("fresh", "hmpc_pin/model/robot.py", "moving[link] = movable or moves(par, depth + 1)", "moving[link] = movable", ["tests/test_inertias.py"]),
    ("fresh", "hmpc_pin/experiment/config/experiment.py", "if beside.is_file() and beside.resolve() != resolved:",
     "if beside.is_file() and beside.resolve() == resolved:", ["tests/test_moved_configs.py"]),
    ("fresh", "hmpc_pin/realtime/process_arm.py", "            self.close(wait=0.0)", "            pass",
     ["tests/test_interrupts.py", "-k", "any_instant and realtime"]),
    ("fresh", "hmpc_pin/_startup.py", "            return next(args, None) in names", "            return False",
     ["tests/test_interrupts.py", "-k", "any_instant and run"]),
    ("fresh", "hmpc_pin/apps/cli.py", 'if touch is not None and line.startswith("tracking error"):',
     'if touch is None and line.startswith("tracking error"):', ["tests/test_cli_outputs.py"]),
    ("fresh", "hmpc_pin/controllers/computed_torque.py", 'if not getattr(self, "_was_reset", False):',
     'if getattr(self, "_was_reset", True) is None:', [LV]),
    ("fresh", "hmpc_pin/sim/mujoco.py", "        tau = held_torque(self, tau)", "        tau = np.asarray(tau, dtype=float)", [LV]),
    ("fresh", "hmpc_pin/apps/viz.py", "        _meshcat()", "        pass", ["tests/test_cli_outputs.py"]),
    # ---- issue 36's code (check, identify, tune, identification, the observer record,
    # install_command), written down before looking at which tests would catch them
    ("i36", "hmpc_pin/apps/check.py", "tau = pin.rnea(model, data, q[k], dq[k], ddq[k]) + b * dq[k] + f * np.sign(dq[k])",
     "tau = pin.rnea(model, data, q[k], dq[k], ddq[k]) + f * np.sign(dq[k])", [CHK]),
    ("i36", "hmpc_pin/apps/check.py", "tau = tau - np.asarray(disturbance(float(t[k]), q[k], dq[k]), dtype=float)",
     "tau = tau + np.asarray(disturbance(float(t[k]), q[k], dq[k]), dtype=float)", [CHK]),
    ("i36", "hmpc_pin/apps/check.py", "fast = np.flatnonzero(tau < 2 * Ts)", "fast = np.flatnonzero(tau < Ts)", [CHK]),
    ("i36", "hmpc_pin/apps/check.py", "for j in np.flatnonzero(headroom < MIN_HEADROOM):",
     "for j in np.flatnonzero(headroom < 0):", [CHK]),
    ("i36", "hmpc_pin/apps/check.py", "for j in np.flatnonzero(_explicit(config) & (bw * Ts >= 2.0)):",
     "for j in np.flatnonzero(_explicit(config) & (bw * Ts >= 1.0)):", [CHK]),
    ("i36", "hmpc_pin/apps/identify.py", "return ObserverModel.from_record(om, robot, n)",
     "return ObserverModel.from_record(om, robot, None)", [IDF]),
    ("i36", "hmpc_pin/apps/identify.py", "if config and Path(config).is_file():  # an older file without a record",
     "if False:", [IDF]),
    ("i36", "hmpc_pin/identification/friction.py", "return float(np.dot(r[1:], r[:-1]) / rr) if len(r) > 2 and rr > 0 else 0.0",
     "return float(np.dot(r[1:], r[1:]) / rr) if len(r) > 2 and rr > 0 else 0.0", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", "m_eff = m * (1 - rho) / (1 + rho)", "m_eff = m * (1 - rho)", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", "if m_eff - 2 < MIN_DEGREES_OF_FREEDOM:",
     "if m_eff < MIN_DEGREES_OF_FREEDOM:", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", "cover = check_excitation(name, dq, max(excitation_velocity, velocity_threshold),",
     "cover = check_excitation(name, dq, velocity_threshold,", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", 'shift = 1 if self.model_at == "start" else 0', "shift = 0", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", "prev = np.linalg.solve(np.eye(n) + L, prev + L @ phi[k])",
     "prev = prev + L @ (phi[k] - prev)", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", 'implicit = record.get("discretization", "implicit") == "implicit"',
     "implicit = True", [IDN, IDF]),
    # (a mutant of the observer filter's 'nothing after a gap' left with it: it restarts)
    ("i36", "hmpc_pin/identification/friction.py", "sgn = np.tanh(dq / s) if s > 0 else np.sign(dq)",
     "sgn = np.sign(dq)", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/friction.py", 'compensation.discretization == "implicit",',
     "True,", [IDN, IDF]),
    ("i36", "hmpc_pin/identification/thresholds.py", "false_alarm=false_alarm / n,", "false_alarm=false_alarm,",
     ["tests/test_thresholds.py"]),
    ("i36", "hmpc_pin/identification/thresholds.py", "p_block = (1.0 - false_alarm) ** (1.0 / blocks_per_horizon)",
     "p_block = (1.0 - false_alarm) ** blocks_per_horizon", ["tests/test_thresholds.py"]),
    ("i36", "hmpc_pin/apps/tune.py", 'lost = 1.0 - row["t_end"] / duration if duration and "t_end" in row else 0.0',
     'lost = row["t_end"] / duration if duration and "t_end" in row else 0.0', [TUN]),
    ("i36", "hmpc_pin/apps/tune.py", "holdout_seed = (seed + 1) % (MAX_SEED + 1)", "holdout_seed = seed", [TUN]),
    ("i36", "hmpc_pin/apps/tune.py", 'w = cc.observer.bandwidth * (float(params["observer_bandwidth"]) / _bandwidth_scale(cc))',
     'w = cc.observer.bandwidth * 0 + float(params["observer_bandwidth"])', [TUN]),
    ("i36", "hmpc_pin/apps/tune.py", 'p95 = float(np.quantile(rms, 0.95, method="inverted_cdf"))',
     "p95 = float(np.mean(rms))", [TUN]),
    ("i36", "hmpc_pin/experiment/build.py", 'model_at=mpc_settings(cc, n).model_at,',
     'model_at="end",', [IDF]),
    ("i36", "hmpc_pin/exceptions.py", 'wheel = url.startswith("file:") and "archive_info" in record',
     'wheel = url.startswith("file:")', ["tests/test_wheel.py", "-m", "not slow"]),
    ("i36", "hmpc_pin/exceptions.py", """return f'pip install -e "{clone}[{extra}]"'""",
     """return f'pip install "hmpc_pin[{extra}]"'""", ["tests/test_wheel.py", "-m", "not slow"]),
    # ---- the code written for issue 36's last items (loop_radius, observer_lag_error, the
    # run loader, ConfigError's file): written down after the survivors' tests, before running
    ("i36b", "hmpc_pin/apps/check.py", "estimate[iu(1 + m)] -= g * (1.0 - beta)", "estimate[iu(1 + m)] -= g * beta", [CHK]),
    ("i36b", "hmpc_pin/apps/check.py", "h = ((over - (lead - 1)) if i == lead else 1.0) * Ts", "h = Ts", [CHK]),
    # (a mutant of the whole loop's 'decays slower than MIN_DECAY' rule left with the rule)
    ("i36b", "hmpc_pin/apps/check.py", "before = np.vstack([np.zeros((1, n)), d[:-1]])", "before = d", [CHK]),
    ("i36b", "hmpc_pin/apps/check.py", "acc = minv[k] @ (d[k] - dhat[k]) - kp * x - kd * xd",
     "acc = minv[k] @ (d[k] - dhat[k]) - kp * x", [CHK]),
    ("i36b", "hmpc_pin/apps/check.py", "            if t[k] >= after - 1e-12:", "            if t[k] >= 0.0:", [CHK]),
    ("i36b", "hmpc_pin/apps/check.py", "            <= 0.5 * DEFAULT_ERROR_THRESHOLD\n        ):",
     "            <= 2 * DEFAULT_ERROR_THRESHOLD\n        ):", [CHK]),
    ("i36b", "hmpc_pin/apps/check.py", 'if getattr(friction, "sign", None) == "literal":  # the observer must outrun it',
     "if False:", [CHK]),
    ("i36b", "hmpc_pin/apps/runfile.py", 'if head != b"PK\\x03\\x04":', 'if head[:2] != b"PK":', [IDF]),
    ("i36b", "hmpc_pin/apps/runfile.py", "if robot.nq != n or (names and tuple(robot.joint_names) != names):",
     "if robot.nq != n:", [IDF]),
    ("i36b", "hmpc_pin/apps/cli.py", 'robot = run_robot(result, str(args.urdf) if args.urdf else None, "RESULT")',
     'robot = run_robot(result, None, "RESULT")', [IDF, "tests/test_cli.py", "-k", "replay"]),
    ("i36b", "hmpc_pin/exceptions.py", 'what = f"{key}: " if key else ""', 'what = f"{key}: "', ["tests/test_errors.py"]),
    # ---- issue 36's code once more, after the explicit observer's loop was modelled: a fresh
    # group spread over check, identification, identify, the run loader, thresholds, tune and
    # install_command, written down and committed before any of them ran
    ("i36c", "hmpc_pin/apps/check.py", "coeffs[2 + m] -= g * beta", "coeffs[1 + m] -= g * beta", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "A, B = hold((over - (m - 1) if i == m else 1.0) * Ts)", "A, B = hold(Ts)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "step[2 + i, 1 + i] = 1.0", "step[2 + i, 2 + i] = 1.0", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "step[iu(j), iu(j - 1)] = 1.0", "step[iu(j), iu(j)] = 1.0", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "    u = v - estimate", "    u = v + estimate", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "if decay < MIN_DECAY * decay0:", "if decay < 0.25 * decay0:", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "bad = np.flatnonzero(((radius >= 1.0) | ((radius >= MAX_RADIUS) & slower)) & (own < 1.0))",
     "bad = np.flatnonzero(((radius >= 1.0) | (radius >= MAX_RADIUS)) & (own < 1.0))", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "x, xd = x + Ts * xd + 0.5 * Ts * Ts * acc, xd + Ts * acc",
     "x, xd = x + Ts * xd, xd + Ts * acc", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "model = replace(model, matrix=np.asarray(model.matrix) * scale)",
     "model = replace(model, matrix=np.asarray(model.matrix))", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "bad = np.flatnonzero(err > DEFAULT_ERROR_THRESHOLD)",
     "bad = np.flatnonzero(err > 2 * DEFAULT_ERROR_THRESHOLD)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "for power in range(1, 13):", "for power in range(2, 13):", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "ddq = np.gradient(dq, dt, axis=0)", "ddq = np.gradient(dq, Ts, axis=0)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "need = np.maximum(need, np.abs(tau))", "need = np.maximum(need, tau)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "if not fast.size or controller == plant == True:",
     "if not fast.size or controller == plant:", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", '{"controller.joint_dynamics": True},', '{"controller.joint_dynamics": False},', [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", 'report.add_problem(f"{text}; choose a compensation (an observer)", None)',
     'report.warnings.append(f"{text}; choose a compensation (an observer)")', [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "return np.log(np.minimum(radius, 1.0)) > MIN_DECAY * np.log(implicit)",
     "return np.log(np.minimum(radius, 1.0)) > np.log(implicit)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "bad = np.flatnonzero(explicit_loop_slow(kp, kd, Ts, bw * Ts, ratio) & (bw * Ts < 2.0))",
     "bad = np.flatnonzero(explicit_loop_slow(kp, kd, Ts, bw * Ts, ratio))", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "level = level.setdefault(table, {})", "level = nested.setdefault(table, {})", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "ratio = np.where(m_plant > 0, m_model / m_plant, 1.0)",
     "ratio = np.where(m_plant > 0, m_plant / m_model, 1.0)", [CHK]),
    ("i36c", "hmpc_pin/apps/check.py", "uncompensated = 0.0 if latency > 0 else Ts", "uncompensated = Ts", [CHK]),
    ("i36c", "hmpc_pin/identification/friction.py",
     "m_effs = [len(r) * (1 - max(0.0, _lag1(r))) / (1 + max(0.0, _lag1(r))) for r in res]",
     "m_effs = [len(r) * (1 - _lag1(r)) / (1 + _lag1(r)) for r in res]", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "half = student_t.ppf(0.5 + confidence / 2,",
     "half = student_t.ppf(confidence,", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "qm = 0.5 * (q[k] + q[k + 1])", "qm = q[k]", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "valid = valid[:-1] & valid[1:]  # per period: both ends recorded",
     "valid = valid[:-1]  # per period: both ends recorded", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "prev = (prev + a * phi[k]) / (1 + a)",
     "prev = prev + a * (phi[k] - prev)", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "dq = np.vstack([clean.dq[:1], 0.5 * (clean.dq[1:] + clean.dq[:-1])])",
     "dq = clean.dq", [IDN, IDF]),
    ("i36c", "hmpc_pin/identification/friction.py", "if min(forward, backward) < min_coverage:",
     "if max(forward, backward) < min_coverage:", [IDN, IDF]),
    ("i36c", "hmpc_pin/apps/identify.py", "if args.after is not None and not args.after < t1:",
     "if args.after is not None and not args.after <= t1:", [IDF]),
    ("i36c", "hmpc_pin/apps/identify.py", "after=args.after if args.after is not None else 0.5,",
     "after=args.after if args.after is not None else 0.0,", [IDF]),
    ("i36c", "hmpc_pin/apps/runfile.py", "np.all(np.diff(t) > 0)):", "np.all(np.diff(t) >= 0)):", [IDF]),
    ("i36c", "hmpc_pin/apps/runfile.py", "if t.ndim != 1 or len(t) < 2:", "if t.ndim != 1 or len(t) < 1:", [IDF]),
    ("i36c", "hmpc_pin/identification/thresholds.py", "block = min(block, span / 10)", "block = min(block, span)",
     ["tests/test_thresholds.py"]),
    ("i36c", "hmpc_pin/identification/thresholds.py", "if per_block < 10:", "if per_block < 2:", ["tests/test_thresholds.py"]),
    ("i36c", "hmpc_pin/apps/tune.py", "excess = max(0.0, tv / tv0 - 1.0) if tv0 else 0.0",
     "excess = tv / tv0 - 1.0 if tv0 else 0.0", [TUN]),
    ("i36c", "hmpc_pin/apps/tune.py", 'space["observer_gain"] = ("log", c0 / 10, c0 * 5)',
     'space["observer_gain"] = ("log", c0 / 10, c0)', [TUN]),
    ("i36c", "hmpc_pin/exceptions.py", 'if (clone / "pyproject.toml").is_file() and (clone / "CMakeLists.txt").is_file():',
     'if (clone / "pyproject.toml").is_file() or (clone / "CMakeLists.txt").is_file():',
     ["tests/test_wheel.py", "-m", "not slow"]),
    # ---- a second fresh group after the i36c survivors' tests, over the same code (none of
    # these lines was mutated before), written down and committed before any of them ran
    ("i36d", "hmpc_pin/apps/check.py", "coeffs[1 + m] -= g * (1.0 - beta)", "coeffs[1 + m] -= g", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "predict[:, 1 + i] += B", "predict[:, 1 + i] -= B", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "gain = -np.array([kp, kd]) @ predict  # u_k", "gain = -np.array([kp, kd]) @ np.eye(2, size)  # u_k", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "estimate[2] = 1.0 - g", "estimate[2] = 1.0", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "step[iv(1)] = v", "step[iv(1)] = u", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "predict[:, iv(i)] += np.array([0.5 * h * h, h])", "predict[:, iv(i)] += np.array([h * h, h])", [CHK]),
    # (a mutant of the whole loop's 'decays slower than MIN_DECAY' rule left with the rule)
    ("i36d", "hmpc_pin/apps/check.py", "own = np.array([overdeclared_radius(w * Ts, ratio, 0.0, explicit) for w in bw])",
     "own = np.array([overdeclared_radius(w * Ts, ratio, over, explicit) for w in bw])", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "margin = np.where(bw > 0, limit / np.where(bw > 0, bw, 1.0), np.inf)",
     "margin = np.where(bw > 0, bw / limit, np.inf)", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "over = np.flatnonzero(margin < 1.0 - 1e-9)", "over = np.flatnonzero(margin < 0.5)", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "        b, f = np.zeros(n), np.zeros(n)", "        b, f = b, f", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "t = np.arange(0.0, ex.config.simulation.duration + dt / 2, dt)",
     "t = np.arange(0.0, ex.config.simulation.duration / 2, dt)", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "minv = np.array([np.linalg.inv(ex.robot.mass_matrix(q[k])) for k in range(len(t))])",
     "minv = np.array([np.linalg.inv(ex.robot.mass_matrix(q[0])) for k in range(len(t))])", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "model = replace(model, gain=np.asarray(model.gain, dtype=float) * scale)",
     "model = replace(model, gain=np.asarray(model.gain, dtype=float))", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "if not bad.size or not np.all(np.isfinite(err)):", "if not bad.size:", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", 'key, value = "bandwidth", np.asarray(obs.bandwidth, dtype=float) * scale',
     'key, value = "gain", np.asarray(obs.bandwidth, dtype=float) * scale', [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", 'listed = ", ".join(f"{names[j]!r} ({tau[j]:.3g} s)" for j in fast)',
     'listed = ", ".join(f"{names[j]!r} ({tau[j]:.3g} s)" for j in range(len(names)))', [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "use w < {2 / Ts:.4g} 1/s", "use w < {1 / Ts:.4g} 1/s", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "                if err > ENGINE_RTOL:", "                if err > 10 * ENGINE_RTOL:", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", 'if config.plant.engine == "mujoco":  # the simulated arm is not the model', "if False:", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "if friction is not None or (pulse is not None and np.any(np.asarray(pulse.amplitude))):",
     "if friction is not None:", [CHK]),
    ("i36d", "hmpc_pin/apps/check.py", "implicit = np.array([loop_radius(kp, kd, Ts, w, 0.0, ratio) for w in wTs])",
     "implicit = np.array([loop_radius(kp, kd, Ts, w, 0.0, ratio, True) for w in wTs])", [CHK]),
    ("i36d", "hmpc_pin/identification/friction.py", "if not (np.isfinite(Ts) and Ts > 0):", "if not np.isfinite(Ts):", [IDN, IDF]),
    ("i36d", "hmpc_pin/identification/friction.py", '"discretization": "implicit" if self.implicit else "explicit",',
     '"discretization": "implicit" if True else "explicit",', [IDN, IDF]),
    ("i36d", "hmpc_pin/identification/friction.py", "    return a * dq + b * sgn", "    return a * dq - b * sgn", [IDN, IDF]),
    ("i36d", "hmpc_pin/identification/friction.py", "f[k] = tau[k] - Y @ pi", "f[k] = tau[k] + Y @ pi", [IDN, IDF]),
    ("i36d", "hmpc_pin/identification/friction.py", "scale = chi2 / max(m - p, 1)", "scale = chi2 / max(m, 1)", [IDN, IDF]),
    ("i36d", "hmpc_pin/identification/thresholds.py",
     "threshold=safety * (np.maximum(thr, r.max(axis=0)) if floor_at_peak else thr),",
     "threshold=safety * thr,", ["tests/test_thresholds.py"]),
    ("i36d", "hmpc_pin/apps/identify.py", "        if getattr(args, key) is not None:", "        if getattr(args, key):", [IDF]),
    ("i36d", "hmpc_pin/apps/identify.py", "    if path.is_dir():", "    if False:", [IDF]),
    ("i36d", "hmpc_pin/apps/runfile.py", "    if not head:", "    if head is None:", [IDF]),
    ("i36d", "hmpc_pin/apps/runfile.py", "        if not np.issubdtype(np.asarray(arr).dtype, np.number):", "        if False:", [IDF]),
    ("i36d", "hmpc_pin/apps/tune.py", "holdout = samples if holdout is None else holdout", "holdout = samples", [TUN]),
    ("i36d", "hmpc_pin/apps/tune.py", "if not duration > after:", "if not duration >= after:", [TUN]),
    ("i36d", "hmpc_pin/apps/tune.py", "out[name] = min(spec[1], key=lambda c, v=v: abs(c - v))", "out[name] = spec[1][0]", [TUN]),
    ("i36d", "hmpc_pin/exceptions.py", "if wheel and Path(unquote(urlparse(url).path)).is_file():", "if wheel:",
     ["tests/test_wheel.py", "-m", "not slow"]),
    # ---- a third fresh group after the i36d survivors' tests, over lines of the same code not
    # mutated before, written down and committed before any of them ran
    ("i36e", "hmpc_pin/apps/check.py", "return float(max(np.max(ratio), 1e-3))", "return float(max(np.min(ratio), 1e-3))", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", 'cc.compensation != "momentum" and getattr(cc.observer, "discretization"',
     'cc.compensation == "momentum" and getattr(cc.observer, "discretization"', [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", "np.broadcast_to(np.asarray(comp.K, dtype=float), (M0.shape[0],))",
     "np.broadcast_to(np.asarray(comp.K, dtype=float) * M0[0, 0], (M0.shape[0],))", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", "excess = overdeclared_excess(Ts, latency)", "excess = overdeclared_excess(Ts, 2 * latency)", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", "nu = m + 2  # u_{k-1} .. u_{k-2-m}", "nu = m + 1  # u_{k-1} .. u_{k-2-m}", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", "        step[2] = gain", "        step[2] = -gain", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", "        dhat = np.zeros_like(d)", "        dhat = d", [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", 'wts = "-" if self.bandwidth is None else f"{self.bandwidth[j] * self.Ts:.3g}"',
     'wts = "-" if self.bandwidth is None else f"{self.bandwidth[j]:.3g}"', [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", 'else f"{100 * self.headroom[j]:.0f} %"', 'else f"{self.headroom[j]:.0f} %"', [CHK]),
    ("i36e", "hmpc_pin/apps/check.py", 'f"effort limit (headroom {100 * headroom[j]:.0f} %, expected >= "',
     'f"effort limit (headroom {100 * (1 - headroom[j]):.0f} %, expected >= "', [CHK]),
    ("i36e", "hmpc_pin/identification/friction.py", "keep = np.isfinite(y) & np.isfinite(dq) & (np.abs(dq) > velocity_threshold)",
     "keep = np.isfinite(y) & np.isfinite(dq)", [IDN, IDF]),
    ("i36e", "hmpc_pin/identification/friction.py", "for v in self.viscous)}]   # [N·m·s/rad]", "for v in self.coulomb)}]   # [N·m·s/rad]", [IDN, IDF]),
    ("i36e", "hmpc_pin/identification/friction.py", "rank = int(np.count_nonzero(d > tol * d[0])) if d.size else 0", "rank = len(d)", [IDN, IDF]),
    ("i36e", "hmpc_pin/identification/friction.py", "ddq = (dq[k + 1] - dq[k]) / (t[k + 1] - t[k])", "ddq = (dq[k + 1] - dq[k]) / (t[1] - t[0])", [IDN, IDF]),
    ("i36e", "hmpc_pin/identification/thresholds.py", "if np.ptp(maxima) == 0:", "if False:", ["tests/test_thresholds.py"]),
    ("i36e", "hmpc_pin/identification/thresholds.py", '("--safety", safety, np.isfinite(safety) and safety >= 1),',
     '("--safety", safety, np.isfinite(safety) and safety > 1),', ["tests/test_thresholds.py"]),
    ("i36e", "hmpc_pin/identification/thresholds.py", "use = t >= after - 1e-12", "use = t > after", ["tests/test_thresholds.py"]),
    ("i36e", "hmpc_pin/apps/identify.py", "if pulse is None or not np.any(np.asarray(pulse.amplitude) != 0):",
     "if pulse is None:", [IDF]),
    ("i36e", "hmpc_pin/apps/identify.py", 'suffix = "collision" if args.thresholds else "friction"',
     'suffix = "friction"', [IDF]),
    ("i36e", "hmpc_pin/apps/runfile.py", "n = np.asarray(result.q).shape[-1] if np.ndim(result.q) == 2 else None",
     "n = np.asarray(result.q).shape[0] if np.ndim(result.q) == 2 else None", [IDF]),
    ("i36e", "hmpc_pin/apps/runfile.py", 'gravity=result.meta.get("gravity", 9.81),', "gravity=9.81,", [IDF]),
    ("i36e", "hmpc_pin/apps/tune.py", "rms = min(rms, 10 * error_bound) if np.isfinite(rms) else 10 * error_bound",
     "rms = 10 * error_bound", [TUN]),
    ("i36e", "hmpc_pin/apps/tune.py", "bad = [o for o in observers if o not in names]",
     "bad = [o for o in observers if o in names]", [TUN]),
    ("i36e", "hmpc_pin/apps/tune.py", "out[name] = type(v)(min(max(v, spec[1]), spec[2]))", "out[name] = v", [TUN]),
    ("i36e", "hmpc_pin/exceptions.py", """f'pip install -e ".[{extra}]")'""", """f'pip install ".[{extra}]")'""",
     ["tests/test_wheel.py", "-m", "not slow"]),
    # ---- a fourth fresh group, over lines of issue 36's area no group mutated (checks.py's
    # converters, check's table and fix, observer_modes, the friction fit's helpers, the
    # thresholds' table, identify's options, the run loader, tune's space and options, the
    # check command, install_command), written down and committed before any of them ran
    ("i36f", "hmpc_pin/checks.py", "if nonneg and x < 0:", "if nonneg and x <= 0:", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/checks.py", "    if x > MAX_LATENCY:", "    if x >= 2 * MAX_LATENCY:", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/checks.py", "if minimum is not None and value < minimum:", "if minimum is not None and value < minimum - 1:", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/checks.py", "if eig.min() < 0 or eig.max() <= 0:", "if eig.min() < 0:", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/checks.py", "    if not np.allclose(arr, arr.T):", "    if False:", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/checks.py", "if nonneg and np.any(arr < 0):", "if nonneg and np.all(arr < 0):", [LV, "tests/test_config.py"]),
    ("i36f", "hmpc_pin/apps/check.py", 'else f"{self.margin[j]:.2g}x"', 'else f"{1 / self.margin[j]:.2g}x"', [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", 'else f"{self.damping_tau[j]:.3g}"', 'else f"{1 / self.damping_tau[j]:.3g}"', [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", 'f"MuJoCo: M(q) within {self.engine[0]:.2g}, forward dynamics within "',
     'f"MuJoCo: M(q) within {self.engine[1]:.2g}, forward dynamics within "', [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "k: changed(getattr(obj, k), v) if isinstance(v, dict) else v", "k: v", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "err_M = max(err_M, float(np.abs(M_mj - M_pin).max() / np.abs(M_pin).max()))",
     "err_M = max(err_M, float(np.abs(M_mj - M_pin).max()))", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "limit = overdeclared_limit(Ts, excess) if latency > 0 else bandwidth_limit(Ts, uncompensated)",
     "limit = bandwidth_limit(Ts, uncompensated)", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "w = [np.linalg.eigvals(np.linalg.solve(ex.robot.mass_matrix(qk), cY)).real for qk in q]",
     "w = [np.linalg.eigvals(np.linalg.solve(ex.robot.mass_matrix(ex.q0), cY)).real for qk in q]", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "        j = i[np.argmax(w[i])]", "        j = i[0]", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "return np.where(np.isfinite(limit), 1.0 - need / limit, np.inf)",
     "return np.where(np.isfinite(limit), 1.0 - need / limit, 1.0)", [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", 'if getattr(friction, "sign", None) != "literal":', 'if getattr(friction, "sign", None) == "physical":', [CHK]),
    ("i36f", "hmpc_pin/apps/check.py", "m = math.ceil(over - 1e-9) if over > 0 else 0", "m = math.floor(over + 1e-9) if over > 0 else 0", [CHK]),
    ("i36f", "hmpc_pin/identification/friction.py", "    total = max(len(dq), 1)",
     "    total = max(np.count_nonzero(np.abs(dq) > velocity_threshold), 1)", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "cond = float(np.linalg.cond(A / np.linalg.norm(A, axis=0)))", "cond = float(np.linalg.cond(A))", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "var = [max(float(np.mean((v - a @ theta) ** 2)), 1e-300) for a, v in blocks]",
     "var = [1.0 for a, v in blocks]", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "residual_rms=float(np.sqrt(np.mean(r * r))),", "residual_rms=float(np.sqrt(np.sum(r * r))),", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "if g.ndim == 1 and compensation_spec(kind).Y is not None:", "if False:", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", 'model_at = record.get("model_at", "end")', 'model_at = record.get("model_at", "start")', [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "Y[k] = pin.computeJointTorqueRegressor(model, data, 0.5 * (q[k] + q[k + 1]), dq_mid[k], ddq)",
     "Y[k] = pin.computeJointTorqueRegressor(model, data, q[k], dq_mid[k], ddq)", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", 'columns["tau_applied"] = np.vstack([tau[:-1], np.zeros((1, tau.shape[1]))])',
     'columns["tau_applied"] = tau', [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", 'a, b = np.asarray(ff["viscous"], float), np.asarray(ff["coulomb"], float)',
     'a, b = np.asarray(ff["coulomb"], float), np.asarray(ff["viscous"], float)', [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "    if not 0 < confidence < 1:", "    if not 0 < confidence <= 1:", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "        use = (t >= after - 1e-12) & valid", "        use = valid", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "ff = np.vstack([np.zeros((1, n)), _feedforward(clean, clean.dq[:-1])])",
     "ff = _feedforward(clean, clean.dq)", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", "f\"coulomb = [{', '.join(f'{v:.6g}' for v in self.coulomb)}]   # [N·m]\",",
     "f\"coulomb = [{', '.join(f'{v:.3g}' for v in self.coulomb)}]   # [N·m]\",", [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/friction.py", 'f"{j.samples} ({j.effective_samples:.0f}) | "', 'f"{j.samples} ({j.samples}) | "', [IDN, IDF]),
    ("i36f", "hmpc_pin/identification/thresholds.py", "f\"threshold = [{', '.join(f'{v:.6g}' for v in self.threshold)}]   # [N·m]\",",
     "f\"threshold = [{', '.join(f'{v:.3g}' for v in self.threshold)}]   # [N·m]\",", ["tests/test_thresholds.py"]),
    ("i36f", "hmpc_pin/identification/thresholds.py", '("--horizon", horizon, np.isfinite(horizon) and horizon > 0),',
     '("--horizon", horizon, horizon > 0),', ["tests/test_thresholds.py"]),
    ("i36f", "hmpc_pin/identification/thresholds.py", ".reshape(m, samples_per_block).max(axis=1)", ".reshape(m, samples_per_block).mean(axis=1)",
     ["tests/test_thresholds.py"]),
    ("i36f", "hmpc_pin/apps/identify.py", "while all(isinstance(v, dict) for v in body.values()) and len(body) == 1:", "while False:", [IDF, IDN]),
    ("i36f", "hmpc_pin/apps/identify.py", "        if getattr(args, key) is None:\n            setattr(args, key, default)",
     "        if not getattr(args, key):\n            setattr(args, key, default)", [IDF]),
    ("i36f", "hmpc_pin/apps/identify.py", "    if not folder.is_dir():", "    if False:", [IDF]),
    ("i36f", "hmpc_pin/apps/identify.py", "rows = zip(fit.names, fit.threshold, fit.peak, strict=True)", "rows = zip(fit.names, fit.peak, fit.threshold, strict=True)", [IDF]),
    ("i36f", "hmpc_pin/apps/runfile.py", 'for name in ("q", "dq", "tau", "d_hat", "tau_applied"):', 'for name in ("q", "dq"):', [IDF]),
    ("i36f", "hmpc_pin/apps/runfile.py", 'locked_joints=result.meta.get("locked_joints") if not urdf else None,', "locked_joints=None,", [IDF]),
    ("i36f", "hmpc_pin/apps/runfile.py", "    if not isinstance(result.meta, dict):", "    if False:", [IDF]),
    ("i36f", "hmpc_pin/apps/tune.py", '"Q_velocity": float(cc.Q[1, 1]),', '"Q_velocity": float(cc.Q[0, 0]),', [TUN]),
    ("i36f", "hmpc_pin/apps/tune.py", "if not (np.array_equal(cc.Q, Q) and np.array_equal(cc.P, 2 * Q)):", "if not np.array_equal(cc.Q, Q):", [TUN]),
    ("i36f", "hmpc_pin/apps/tune.py", "all(np.isfinite(v) and v > 0 for v in ts)", "all(np.isfinite(v) and v >= 0 for v in ts)", [TUN]),
    ("i36f", "hmpc_pin/apps/tune.py", 'sat = float(np.mean([r["saturation"] for r in rows]))', 'sat = float(np.max([r["saturation"] for r in rows]))', [TUN]),
    ("i36f", "hmpc_pin/apps/tune.py", "seed=(seed + len_trials(optuna, storage, name)) % (MAX_SEED + 1)", "seed=seed % (MAX_SEED + 1)", [TUN]),
    ("i36f", "hmpc_pin/apps/tune.py", "if holdout_seed is not None and holdout == 0:", "if holdout_seed is not None and not holdout:", [TUN]),
    ("i36f", "hmpc_pin/apps/cli.py", '        return EXIT_FAILED\n    print("no problem found")', '        return EXIT_OK\n    print("no problem found")', [CHK]),
    ("i36f", "hmpc_pin/exceptions.py", """return f'pip install "hmpc_pin[{extra}] @ {url}"'""", """return f'pip install "hmpc_pin[{extra}]"'""",
     ["tests/test_wheel.py", "-m", "not slow"]),
    # ---- a fifth fresh group, after the i36f survivors' tests, over lines of the same
    # area no group mutated, written down and committed before any of them ran
    ("i36g", "hmpc_pin/apps/check.py", "base, lead = lead_radius(kp, kd, Ts, 0.0), lead_radius(kp, kd, Ts, over)",
     "base, lead = lead_radius(kp, kd, Ts, 0.0), lead_radius(kp, kd, Ts, 2 * over)", [CHK]),
    ("i36g", "hmpc_pin/apps/check.py", "decay, decay0 = -math.log(min(lead, 1.0)) / Ts, -math.log(base) / Ts",
     "decay, decay0 = -math.log(min(lead, 1.0)) / Ts, -math.log(base)", [CHK]),
    ("i36g", "hmpc_pin/apps/check.py", "    ratio = _run_ratio(ex)\n    bad = np.flatnonzero(explicit_loop_slow",
     "    ratio = 1.0\n    bad = np.flatnonzero(explicit_loop_slow", [CHK]),
    ("i36g", "hmpc_pin/apps/check.py", "k = int(min(samples, max(duration / Ts, 1.0)))", "k = int(samples)", [CHK]),
    ("i36g", "hmpc_pin/apps/check.py", "t = np.linspace(0.0, duration, k + 1)", "t = np.linspace(0.0, duration / 2, k + 1)", [CHK]),
    ("i36g", "hmpc_pin/apps/check.py", "plant_damped = bool(config.plant.joint_dynamics)", "plant_damped = True", [CHK]),
    ("i36g", "hmpc_pin/identification/friction.py", 'return f"{value:.{digits}g} [{ci[0]:.{digits}g}, {ci[1]:.{digits}g}]"',
     'return f"{value:.{digits}g} [{ci[1]:.{digits}g}, {ci[0]:.{digits}g}]"', [IDN, IDF]),
    ("i36g", "hmpc_pin/identification/friction.py", "peak = float(np.max(np.abs(dq))) if len(dq) else 0.0",
     "peak = float(np.max(dq)) if len(dq) else 0.0", [IDN, IDF]),
    ("i36g", "hmpc_pin/identification/friction.py", "short = [j for j in self.joints if not j.has_interval]",
     "short = [j for j in self.joints if j.has_interval]", [IDN, IDF]),
    ("i36g", "hmpc_pin/identification/friction.py", 'if source in ("dynamics", "regressor") and robot is None:',
     'if source == "dynamics" and robot is None:', [IDN, IDF]),
    ("i36g", "hmpc_pin/identification/friction.py", "        t = 0.5 * (result.t[1:] + result.t[:-1])", "        t = result.t[:-1]", [IDN, IDF]),
    ("i36g", "hmpc_pin/identification/thresholds.py", "per_block = round(block / Ts) if Ts > 0 else 0",
     "per_block = int(block / Ts) if Ts > 0 else 0", ["tests/test_thresholds.py"]),
    ("i36g", "hmpc_pin/identification/thresholds.py", "        peak=r.max(axis=0),", "        peak=np.abs(result.d_hat).max(axis=0),",
     ["tests/test_thresholds.py"]),
    ("i36g", "hmpc_pin/apps/identify.py", "t0, t1 = float(result.t[0]), float(result.t[-1])", "t0, t1 = 0.0, float(result.t[-1])", [IDF]),
    ("i36g", "hmpc_pin/apps/runfile.py", 'missing = str(exc.args[0] if exc.args else exc).split(" is not a file")[0]',
     "missing = str(exc)", [IDF]),
    ("i36g", "hmpc_pin/apps/tune.py", 'space["N"] = ("int", 5, 30)', 'space["N"] = ("int", 5, 10)', [TUN]),
    ("i36g", "hmpc_pin/apps/tune.py", '"R": ("log", 1e-8, 1e-3),', '"R": ("log", 1e-8, 1e-5),', [TUN]),
    ("i36g", "hmpc_pin/apps/tune.py", 'Ts=float(params.get("Ts", cc.Ts)),', "Ts=float(cc.Ts),", [TUN]),
    ("i36g", "hmpc_pin/apps/tune.py", "out[name] = v if v in spec[1] else spec[1][0]", "out[name] = spec[1][0]", [TUN]),
    # ---- i36h: identify and identification, written before their new tests
    # (end of i36h)
    # ---- i36i: check, checks, thresholds, tune, runfile, written before their new tests
    # (end of i36i)
]


def run(mutant, timeout: float = 600.0) -> tuple[bool, float]:
    _group, file, old, new, tests = mutant
    path = ROOT / file
    text = path.read_text(encoding="utf-8")
    count = text.count(old)
    if count != 1:
        raise SystemExit(f"{file}: {old!r} occurs {count} times; expected once")
    path.write_text(text.replace(old, new), encoding="utf-8")
    start = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests],
            cwd=ROOT, capture_output=True, text=True, timeout=timeout,
        )  # fmt: skip
        killed = proc.returncode != 0
    except subprocess.TimeoutExpired:
        killed = True
    finally:
        path.write_text(text, encoding="utf-8")
    return killed, time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="run the mutants whose file contains this")
    parser.add_argument("--group", default="", help="run one group (new, earlier, fresh, i36 ... i36i)")
    args = parser.parse_args()
    tally: dict[str, list[int]] = {}
    for mutant in MUTANTS:
        if args.only not in mutant[1] or (args.group and mutant[0] != args.group):
            continue
        killed, seconds = run(mutant)
        tally.setdefault(mutant[0], [0, 0])
        tally[mutant[0]][0] += killed
        tally[mutant[0]][1] += 1
        print(f"{'killed ' if killed else 'SURVIVED'} {seconds:5.1f} s  {mutant[1]}: "
              f"{mutant[2]!r} -> {mutant[3]!r}", flush=True)  # fmt: skip
    for group, (k, n) in tally.items():
        print(f"{group}: {k} of {n} killed ({100 * k / n:.0f} %)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
