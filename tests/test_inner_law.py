"""The inner law of the real-time commands (``[realtime] inner_law``, ``--inner-law``;
hmpc_pin.experiment.inner_law): the two-rate laws in the real-time loop against the real
arm process, the threaded law's planner joined on every way out, its record, and the
choice refused where it does not apply (exit 2, one line).

Correctness only: no wall-clock figure is asserted (the machine is shared)."""

from __future__ import annotations

import functools
import json
import os
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.build import Experiment, make_arm_plant
from hmpc_pin.experiment.config import load_config
from hmpc_pin.experiment.controllers import make_compensation
from hmpc_pin.experiment.inner_law import chosen_inner_law, inner_law_controller
from hmpc_pin.native import load as load_native
from hmpc_pin.realtime.inner_law import InnerLawEveryCycle
from hmpc_pin.realtime.loop import LoopSettings, RealtimeLoop
from hmpc_pin.realtime.process_arm import ProcessArm
from hmpc_pin.realtime.safety import SafeTorque, SafetySettings
from hmpc_pin.realtime.threaded_law import InnerLawThreaded

ROOT = Path(__file__).resolve().parents[1]
P = 1e-3  # the arm's period [s] (panda_sine: Ts = 10 ms, the MPC every 10 cycles)


def _config(tmp_path: Path, realtime: str = "", controller: str = "", duration: float = 1.5):
    """panda_sine with keys added to ``[realtime]`` (after :data:`LOOSE`) and
    ``[controller]``, run for ``duration`` [s]."""
    text = (ROOT / "configs" / "panda_sine.toml").read_text()
    text = text.replace("[controller]\n", f"[controller]\n{controller}", 1)
    text = text.replace("[simulation]\nduration = 10.0\n", f"[simulation]\nduration = {duration}\n")
    text += f"\n[realtime]\n{LOOSE}{realtime}"
    path = tmp_path / "panda_sine.toml"
    path.write_text(text)
    return path


#: A loaded machine: neither misses nor a descheduled arm process stop these runs.
LOOSE = "max_misses = 100000\nwatchdog = 2.0\n"


def _live() -> int:
    return int(load_native().PlanThread.live())


class Twin:
    """Both laws on the same states, in the same cycle: the synchronous law's torque is
    written, both are recorded."""

    def __init__(self, a, b):
        self.a, self.b = a, b
        self.Ts = a.Ts
        self.tau_a: list[np.ndarray] = []
        self.tau_b: list[np.ndarray] = []

    @property
    def disturbance_estimate(self):
        return self.a.disturbance_estimate

    def reset(self, q0, dq0):
        self.a.reset(q0, dq0)
        self.b.reset(q0, dq0)
        self.tau_a.clear()
        self.tau_b.clear()

    def step(self, t, q, dq, reference):
        ta = np.array(self.a.step(t, q.copy(), dq.copy(), reference))
        tb = np.array(self.b.step(t, q.copy(), dq.copy(), reference))
        self.tau_a.append(ta)
        self.tau_b.append(tb)
        return ta


def test_every_cycle_and_threaded_wait_give_the_same_torques_in_the_loop(tmp_path):
    """The real-time loop at 1 kHz against the arm process (its plant in wall-clock time):
    the MPC's Python step every 10 cycles and the compiled planner thread (each request
    waited for) on the states the arm sent give the same torque, bit for bit, every cycle
    (two implementations of the MPC: the step's and the planner's own copy of the QPs)."""
    config = load_config(_config(tmp_path, duration=1.0))
    laws = []
    for kind, kw in ((InnerLawEveryCycle, {}), (InnerLawThreaded, {"wait": True})):
        exp = Experiment.from_config(config)
        fast = make_compensation(exp.robot, replace(config.controller, Ts=P), exp.q0)
        laws.append(kind(exp.controller, fast, P, exp.effort_limit, **kw))
    twin = Twin(*laws)
    safety = SafetySettings.unlimited(exp.robot.nq, max_misses=10**6, watchdog=2.0, hold=0.05)
    arm = ProcessArm(
        functools.partial(make_arm_plant, config), exp.q0, exp.dq0, effort_limit=exp.effort_limit
    )
    try:
        loop = RealtimeLoop(
            arm, twin, exp.reference, SafeTorque(exp.robot), LoopSettings(1.0 / P, 1.0), safety
        )
        run = loop.run(exp.q0, exp.dq0)
    finally:
        arm.close()
        laws[1].close()
    # (a loaded machine skips cycles, and a state far from the plan after a long stall
    # can end the run with a QP not solved in time: the torques up to there are compared)
    assert len(twin.tau_a) > 200, run.result.message
    a, b = np.array(twin.tau_a), np.array(twin.tau_b)
    np.testing.assert_array_equal(a, b)
    # and it is the MPC's answer that changes them (not a constant): the torques move
    assert np.ptp(a, axis=0).max() > 0.1
    assert laws[1].fallbacks == 0  # each plan waited for: never stale
    assert not laws[1].planner.running


def test_a_threaded_run_completes_and_records_its_plans_and_fallbacks(tmp_path):
    """``hmpc-pin realtime --inner-law threaded``: the run completes, its record (the
    JSON and the npz's meta) says which law ran, with the planner's counts; its planner is
    joined at the end."""
    live = _live()
    cfg = _config(tmp_path, duration=1.5)
    out = tmp_path / "out"
    assert main(["realtime", str(cfg), "--inner-law", "threaded", "--out", str(out)]) == 0
    assert _live() == live
    summary = json.loads((out / "panda_sine_realtime.json").read_text())
    law = summary["realtime"]["inner_law"]
    assert law["name"] == "threaded" and law["mpc_every"] == 10
    # a plan asked for every 10th cycle that ran; each answered or replaced by a newer one
    cycles = summary["realtime"]["cycles_run"]
    assert law["requests"] >= cycles // 10
    assert law["requests"] - law["dropped"] - 1 <= law["published"] <= law["requests"]
    # every cycle without a plan within max_age braked, and was counted as such
    assert law["fallbacks"] == law["refused"]
    assert law["max_age"] == pytest.approx(0.02)
    assert summary["realtime"]["decimation"] == 1  # the law runs every cycle
    from hmpc_pin.sim.result import Result

    saved = Result.load(out / "panda_sine_realtime.npz")
    assert saved.meta["realtime"]["inner_law"]["name"] == "threaded"


def test_the_planner_is_joined_after_a_safe_stop_and_an_exception(tmp_path, monkeypatch):
    """A safe stop (the measured speed beyond a tight velocity bound) and an exception
    before the loop's first cycle: the threaded law's planner thread is joined on both
    ways out."""
    from hmpc_pin.apps import realtime as app

    live = _live()
    tight = "velocity_scale = 0.01\ninner_law = 'threaded'\n"
    config = load_config(_config(tmp_path, tight, duration=3.0))
    run, _ = app.run_realtime(config, tmp_path)
    assert not run.result.complete and run.stop["cause"] != "interrupted"
    assert "rad/s, beyond its bound" in run.stop["reason"], run.stop
    assert run.stats["inner_law"]["name"] == "threaded"
    assert _live() == live

    made = []
    original = app.inner_law_controller

    def spy(*args, **kw):
        law = original(*args, **kw)
        made.append(law)
        return law

    def broken(*args, **kw):
        raise RuntimeError("the status line failed")

    monkeypatch.setattr(app, "inner_law_controller", spy)
    monkeypatch.setattr(app, "StatusLine", broken)
    with pytest.raises(RuntimeError, match="status line"):
        app.run_realtime(replace(config, realtime=replace(config.realtime)), tmp_path)
    assert len(made) == 1 and isinstance(made[0], InnerLawThreaded)
    assert not made[0].planner.running
    assert _live() == live


#: (options, [realtime] keys, [controller] keys, the one line's pattern)
BAD = [
    (["--inner-law", "fast"], "", "", r"--inner-law: expected one of auto, whole-step"),
    ([], "inner_law = 'fast'\n", "", r"realtime\.inner_law: expected one of"),
    (["--inner-law", "every-cycle"], "", "Ts = 0.001\n", r"--inner-law: every-cycle does not"),
    ([], "inner_law = 'every-cycle'\n", "latency = 0.002\n", r"realtime\.inner_law:.*latency"),
    # the planner's scheduling: only with the threaded law, and a valid one
    ([], "planner = 'fifo'\n", "", r"realtime\.planner: does not apply: the inner law is whole"),
    (["--inner-law", "every-cycle"], "planner = 5\n", "", r"realtime\.planner: does not apply"),
    (
        ["--inner-law", "threaded"],
        "planner = 'fast'\n",
        "",
        r"realtime\.planner: expected \"auto\"",
    ),
    (["--inner-law", "threaded"], "planner = 20\n", "", r"niceness -20\.\.19, got 20"),
    (["--inner-law", "threaded"], "planner = true\n", "", r"realtime\.planner: expected"),
]


@pytest.mark.parametrize(("args", "realtime", "controller", "match"), BAD)
def test_a_bad_inner_law_exits_2_with_one_line(tmp_path, capsys, args, realtime, controller, match):
    import re

    text = (
        _config(tmp_path, realtime).read_text().replace("Ts = 0.01\n", controller or "Ts = 0.01\n")
    )
    if controller.startswith("latency"):
        text = text.replace("[controller]\n", "[controller]\nTs = 0.01\n", 1)
    cfg = tmp_path / "panda_sine.toml"
    cfg.write_text(text)
    out = tmp_path / "out"
    assert main(["realtime", str(cfg), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(match, err), err
    assert not out.exists()  # nothing written


def test_an_inner_law_that_does_not_apply_names_what_to_do(tmp_path):
    """Ts equal to the period, a declared latency, a wrapped controller: each refused
    with the reason and what to do; ``auto`` and ``whole-step`` run anything."""
    config = load_config(_config(tmp_path))
    exp = Experiment.from_config(config)
    with pytest.raises(ConfigError, match=r"use whole-step, or a Ts"):
        chosen_inner_law(exp, 1e-2, "realtime", "every-cycle")
    # the threaded law applies at Ts equal to the period (a long horizon off the cycle)
    assert chosen_inner_law(exp, 1e-2, "realtime", "threaded") == "threaded"
    assert chosen_inner_law(exp, 1e-3, "realtime", "every-cycle") == "every-cycle"
    assert chosen_inner_law(exp, 1e-3, "realtime") == "whole-step"  # auto, realtime's
    assert chosen_inner_law(exp, 1e-3, "franka") == "every-cycle"  # auto, Franka's
    assert chosen_inner_law(exp, 1e-2, "franka") == "whole-step"
    from hmpc_pin.controllers.base import ControllerWrapper

    wrapped = replace(exp, controller=ControllerWrapper(exp.controller))
    with pytest.raises(ConfigError, match=r"not the hierarchical MPC.*whole-step"):
        chosen_inner_law(wrapped, 1e-3, "ros", "threaded")
    assert inner_law_controller(wrapped, 1e-3, "ros") is wrapped.controller


def test_the_planner_key_schedules_the_threaded_laws_thread(tmp_path):
    """``[realtime] planner = 7``: the law built for the run carries it, and its planner
    thread runs at niceness 7 once the first cycle applied it (read back from the OS)."""
    config = load_config(_config(tmp_path, "inner_law = 'threaded'\nplanner = 7\n"))
    exp = Experiment.from_config(config)
    assert chosen_inner_law(exp, P, "realtime") == "threaded"
    law = inner_law_controller(exp, P, "realtime")
    with law:
        assert isinstance(law, InnerLawThreaded) and law.planner_scheduling == 7
        q0 = np.asarray(exp.q0, dtype=float)
        law.reset(q0, np.zeros_like(q0))
        law.step(0.0, q0, np.zeros_like(q0), exp.reference)
        tid = law.planner.tid
        stat = Path(f"/proc/{os.getpid()}/task/{tid}/stat").read_text()
        niceness = int(stat[stat.rfind(")") + 2 :].split()[16])  # stat's field 19
        assert niceness == law.summary()["planner_nice"] == 7


def test_the_old_names_still_import_with_a_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from hmpc_pin.realtime.franka.rates import InnerLawEveryCycle as Old
        from hmpc_pin.realtime.franka.threaded import InnerLawThreaded as OldThreaded
    assert Old is InnerLawEveryCycle and OldThreaded is InnerLawThreaded
    assert any("hmpc_pin.realtime.inner_law" in str(w.message) for w in caught)
    assert InnerLawEveryCycle.name == "every-cycle" and InnerLawThreaded.name == "threaded"


#: (command line after the config, [realtime] keys, extra tables, the one line's pattern)
OTHER_COMMANDS = [
    (["franka", "--robot-ip", "127.0.0.1", "--inner-law", "fast"], "", "", r"--inner-law: exp"),
    (
        ["franka", "--robot-ip", "127.0.0.1", "--inner-law", "threaded"],
        "",
        "",
        r"--inner-law: threaded does not apply: the controller is a",
    ),
    (["ros", "--inner-law", "every-cycle"], "", "", r"--inner-law: every-cycle does not apply"),
    (["ros"], "inner_law = 'slow'\n", "", r"realtime\.inner_law: expected one of"),
]


@pytest.mark.parametrize(("argv", "realtime", "tables", "match"), OTHER_COMMANDS)
def test_franka_and_ros_refuse_a_bad_inner_law_before_anything(
    tmp_path, capsys, argv, realtime, tables, match
):
    """The same option and key under ``franka`` (before connecting) and ``ros`` (before
    rclpy starts): a [collision] watch wraps the controller, so the two-rate laws do not
    apply to it."""
    import re

    if argv[0] == "ros":
        pytest.importorskip("rclpy")
    cfg = _config(tmp_path, realtime)
    cfg.write_text(cfg.read_text() + "\n[collision]\nthreshold = 1000.0\n" + tables)
    out = tmp_path / "out"
    assert main([argv[0], str(cfg), *argv[1:], "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(match, err), err
    assert not out.exists()
