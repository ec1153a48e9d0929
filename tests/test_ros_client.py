"""The pip-only ROS commands (``ros-params``, ``ros-lifecycle``, ``ros-trajectory``) against a
running ``hmpc-pin ros`` with a fourth participant on the graph, inside a private network
namespace (tests/ros_client_scenario.py); their bad input without any node.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hmpc_pin.apps.cli import main

from .test_ros import HAVE_ROS, run_in_netns

SCENARIO = Path(__file__).with_name("ros_client_scenario.py")

#: 100 Hz (the MPC's rate, one state per step): the least work for a loaded machine, on
#: which each command (a Python process importing rclpy) may take seconds to start; the
#: run is long enough for all of them and ends on the deactivate.
SETTINGS = """
[ros]
rate = 100

[realtime]
max_misses = 1000   # a loaded machine: the commands, not the scheduler, are under test
watchdog = 1.0
"""

TARGET = [0.1, -0.685, 0.1, -2.256, 0.1, 1.671, 0.885]


def test_pip_only_commands_drive_a_running_controller(tmp_path):
    _, report, result = run_in_netns(tmp_path, SCENARIO, "client", 600.0, SETTINGS,
                                          "client.json")  # fmt: skip
    cmds = report["commands"]
    ctrl = report["controller"]
    # the parameters mirror the config, the watchdog as the file sets it
    params = cmds["params"]
    assert params["exit"] == 0, params["stderr"]
    lines = dict(x.split(" = ", 1) for x in params["stdout"].splitlines())
    assert lines["ros.rate"] == "100.0" and lines["realtime.watchdog"] == "1.0"
    assert lines["config.name"] == "'panda_sine'"
    assert cmds["param_rate"]["stdout"].splitlines() == [
        "ros.rate = 100.0",
        "realtime.watchdog = 1.0",
    ]
    assert cmds["param_unknown"]["exit"] == 2
    unknown = cmds["param_unknown"]["stderr"]
    assert "ros.nosuch: /hmpc_pin_controller has no such parameter" in unknown
    assert cmds["get"]["stdout"].strip() == "active"
    # the trajectory reached the node and became the reference: q_ref is the target
    # after its 1 s (the reference held at the last point)
    traj = cmds["trajectory"]
    assert traj["exit"] == 0, traj["stderr"]
    events = result.meta["ros"]["trajectories"]
    assert [e["accepted"] for e in events] == [True], events
    after = result.t > events[0]["t_end"] + 0.1
    assert after.sum() > 5
    np.testing.assert_allclose(result.q_ref[after], np.broadcast_to(TARGET, (after.sum(), 7)),
                               atol=1e-9)  # fmt: skip
    # deactivate answered (a fourth participant on the graph) and ran the stop sequence
    deact = cmds["deactivate"]
    assert deact["exit"] == 0, (deact["stderr"], ctrl["stderr"])
    assert "deactivate done, now inactive" in deact["stdout"]
    assert ctrl["exit"] == 130, ctrl["stderr"]
    assert result.meta["stop"]["cause"] == "deactivated"
    assert not result.complete


@pytest.mark.skipif(not HAVE_ROS, reason="rclpy not installed (extra hmpc_pin[ros])")
@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["ros-trajectory", "panda_sine", "--to", "0,1"], "--to: expected 7 finite positions"),
        (["ros-trajectory", "panda_sine", "--to", "0,0,0,x,0,0,0"], "--to: expected 7"),
        (["ros-trajectory", "panda_sine", "--to", "0,0,0,0,0,0,0", "--in", "-1"], "--in:"),
        (["ros-trajectory", "panda_sine", "--file", "nosuch.csv"], "file not found"),
        (["ros-lifecycle", "get", "--timeout", "0"], "--timeout: expected a time"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv, expected):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err
