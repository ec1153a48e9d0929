"""The safe stops a loaded machine trips: the stop line names the setting to relax (key
and option), ``--watchdog`` / ``--max-misses`` set it for one run and are checked at the
boundary, and after a watchdog stop the loop brakes on states that resume."""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.apps.realtime import with_realtime
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import load_config
from hmpc_pin.realtime.safety import SafetySettings

from .test_realtime import Frozen, P, _setup


@pytest.fixture(scope="module")
def robot(planar3):
    return planar3


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--watchdog", "0"], "argument --watchdog: expected a time [s] > 0, got '0'"),
        (["--watchdog", "nan"], "argument --watchdog: expected a time [s] > 0"),
        (["--max-misses", "0"], "argument --max-misses: expected a whole number >= 1"),
        (["--max-misses", "2.5"], "argument --max-misses: expected a whole number >= 1"),
    ],
)
@pytest.mark.parametrize("command", ["realtime", "ros"])
def test_bad_overrides_are_one_line_and_exit_2(capsys, command, argv, expected):
    with pytest.raises(SystemExit) as exc:
        main([command, "panda_sine", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err


def test_overrides_reach_the_config_and_the_node_parameters():
    from hmpc_pin.apps.ros import config_parameters

    config = load_config("panda_sine")
    assert (config.realtime.watchdog, config.realtime.max_misses) == (0.1, 100)
    changed = with_realtime(config, watchdog=0.5, max_misses=7)
    assert (changed.realtime.watchdog, changed.realtime.max_misses) == (0.5, 7)
    params = config_parameters(changed)
    assert params["realtime.watchdog"] == 0.5 and params["realtime.max_misses"] == 7
    with pytest.raises(ConfigError, match="watchdog"):
        with_realtime(config, watchdog=-1.0)


def test_the_stop_lines_name_the_setting_to_relax(robot):
    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=0.0)
    loop, _, _, _ = _setup(robot, 0.5, safety=safety, wrap=lambda a: Frozen(a, t_stop=0.2))
    run = loop.run()
    assert run.stop["cause"] == "watchdog"
    assert "relax realtime.watchdog (--watchdog S)" in run.stop["reason"]
    loop, _, _, _ = _setup(robot, 0.5, safety=safety, cost=lambda t: 8 * P if t > 0.2 else 0.0)
    run = loop.run()
    assert run.stop["cause"] == "misses"
    assert "relax realtime.max_misses (--max-misses K)" in run.stop["reason"]


class Stalled(Frozen):
    """The stamp frozen from ``t_stop`` for ``length`` of the arm's time, then fresh
    again (a stall of a loaded machine, not an arm gone)."""

    def __init__(self, arm, t_stop, length):
        super().__init__(arm, t_stop=t_stop)
        self.t_resume = t_stop + length

    def read(self):
        stamp, q, dq = self.arm.read()
        if self.t_stop <= stamp < self.t_resume and self._last is not None:
            return self._last
        self._last = (stamp, q.copy(), dq.copy())
        return stamp, q, dq


def test_after_a_watchdog_stop_the_loop_brakes_on_states_that_resume(robot):
    """The stamp freezes for 50 ms mid-motion (watchdog 5 ms): G(q) at once, then, once the
    states resume, the brake on them until every joint is below brake_speed: the arm is
    left still (checked on the arm itself), at G(q) of where it stopped. Without states
    resuming (test_realtime's watchdog case) the same stop ends on G(q) alone."""
    safety = SafetySettings.unlimited(3, max_misses=5, watchdog=0.005, hold=3.0,
                                      brake_speed=0.005)  # fmt: skip
    loop, arm, _, _ = _setup(robot, 0.6, safety=safety, damping=40.0,
                             wrap=lambda a: Stalled(a, t_stop=0.3, length=0.05))  # fmt: skip
    run = loop.run()
    stop, brake = run.stop, run.stop["brake"]
    assert stop["cause"] == "watchdog"
    assert brake["ended"] == "still" and brake["states"] > 0
    assert np.abs(arm.dq).max() < safety.brake_speed
    np.testing.assert_allclose(brake["q"], arm.q, atol=1e-12)
    model = robot.model
    data = model.createData()
    import pinocchio as pin

    G = pin.rnea(model, data, np.asarray(brake["q"]), np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(arm.tau, G, atol=1e-9)
    np.testing.assert_allclose(brake["held_tau"], G, atol=1e-9)
