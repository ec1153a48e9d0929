"""The real-time loop's parts without a run: the loop settings and their keys, the
decimation at its boundaries, the latency statistics against numpy, the tally of misses,
the declared latency through wrappers, the in-process arm against the plant stepped by
hand on an injected clock, and the run's files and lines."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from hmpc_pin.exceptions import ConfigError, DimensionError
from hmpc_pin.model.robot import load_robot
from hmpc_pin.realtime.interface import PlantArm
from hmpc_pin.realtime.loop import (
    LoopSettings,
    _declared_latency,
    _Tally,
    latency_stats,
)
from hmpc_pin.sim.plants import RK4Plant

from .conftest import PLANAR3


@pytest.mark.parametrize("name", ["rate", "duration", "gc_slack"])
@pytest.mark.parametrize("value", [0, -1.0, math.nan, math.inf, "1", None])
def test_loop_settings_name_the_bad_key(name, value):
    with pytest.raises(ConfigError) as info:
        LoopSettings(**{name: value})
    assert info.value.key == f"realtime.{name}"
    assert repr(value) in str(info.value)


@pytest.mark.parametrize("name", ["spin", "warm_up"])
def test_spin_and_warm_up_lie_in_zero_to_one_period(name):
    LoopSettings(rate=500.0, **{name: 0.0})
    LoopSettings(rate=500.0, **{name: 0.002 * (1 - 1e-9)})
    for bad in (0.002, -1e-9, math.nan, "0"):
        with pytest.raises(ConfigError) as info:
            LoopSettings(rate=500.0, **{name: bad})
        assert info.value.key == f"realtime.{name}"
        assert "1/rate = 0.002 s" in str(info.value)


def test_the_decimation_is_a_whole_number_of_periods():
    assert LoopSettings(rate=1000.0).decimation(0.01) == 10
    assert LoopSettings(rate=100.0).decimation(0.01) == 1
    assert LoopSettings(rate=3000.0).decimation(0.01) == 30
    assert LoopSettings(rate=1000.0).period == 1e-3
    for rate in (150.0, 50.0, 1000.0 * (1 + 1e-6), 1.0):
        with pytest.raises(ConfigError) as info:
            LoopSettings(rate=rate).decimation(0.01)
        assert info.value.key == "realtime.rate"
        assert f"rate={rate:g} Hz does not divide the controller period Ts=0.01 s" in str(
            info.value
        )


def test_latency_statistics_are_numpys_percentiles_in_microseconds_of_finite_entries():
    rng = np.random.default_rng(5)
    x = rng.exponential(1e-4, size=2001)
    with_gaps = np.concatenate([x, [np.nan, np.inf, np.nan]])
    s = latency_stats(with_gaps)
    assert s["count"] == 2001
    assert s["median_us"] == pytest.approx(np.median(x) * 1e6, rel=1e-12)
    assert s["p99_us"] == pytest.approx(np.percentile(x, 99.0) * 1e6, rel=1e-12)
    assert s["p999_us"] == pytest.approx(np.percentile(x, 99.9) * 1e6, rel=1e-12)
    assert s["max_us"] == pytest.approx(x.max() * 1e6, rel=1e-12)
    empty = latency_stats(np.array([np.nan, np.nan]))
    assert empty["count"] == 0
    assert all(math.isnan(empty[k]) for k in ("median_us", "p99_us", "p999_us", "max_us"))


def test_the_tally_counts_runs_of_misses_and_skips():
    tally = _Tally()
    assert [tally.miss(3) for _ in range(3)] == [False, False, True]
    assert (tally.misses, tally.consecutive, tally.worst_run) == (3, 3, 3)
    assert not tally.skip(1, 0, 3)  # periods skipped in time add no miss to the run
    assert (tally.misses, tally.skipped) == (3, 1)
    tally.skipped = 0
    tally.consecutive = 0  # (the loop's on-time cycle)
    assert not tally.skip(4, 0, 3)  # skipped in time: no miss
    assert (tally.misses, tally.skipped, tally.consecutive) == (3, 4, 0)
    assert not tally.skip(2, 2, 3)
    assert (tally.misses, tally.skipped, tally.consecutive, tally.worst_run) == (5, 6, 2, 3)
    assert tally.skip(1, 1, 3)  # the third in a row
    assert tally.worst_run == 3
    assert tally.skip(5, 5, 3) and tally.worst_run == 8


def test_the_declared_latency_is_found_through_wrappers():
    from hmpc_pin.realtime.safety import GravityByArm

    inner = SimpleNamespace(latency=0.003)
    assert _declared_latency(inner) == 0.003
    assert _declared_latency(GravityByArm(inner, None)) == 0.003
    assert _declared_latency(SimpleNamespace(controller=SimpleNamespace(latency=2))) == 2.0
    assert _declared_latency(SimpleNamespace()) is None
    assert _declared_latency(SimpleNamespace(latency=None)) is None
    # the outermost object with the setting is the one that runs it
    outer = SimpleNamespace(latency=0.002, controller=SimpleNamespace(latency=0.009))
    assert _declared_latency(outer) == 0.002


# ------------------------------------------------------------------ PlantArm
class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture(scope="module")
def robot():
    return load_robot(PLANAR3)


def _by_hand(robot, q0, taus, P):
    plant = RK4Plant(robot.copy(), None, P, P)
    plant.reset(q0, np.zeros(3), 0.0)
    q, dq = q0, np.zeros(3)
    for tau in taus:
        q, dq = plant.advance(tau)
    return q, dq


def test_the_plant_arm_holds_still_until_written_then_steps_whole_periods(robot):
    P = 0.002
    q0 = np.array([0.1, -0.2, 0.3])
    clock = Clock()
    arm = PlantArm(RK4Plant(robot.copy(), None, P, P), q0, clock=clock, effort_limit=4.0)
    clock.t += 1.0  # a second on its brakes
    t, q, dq = arm.read()
    assert t == 0.0
    np.testing.assert_array_equal(q, q0)
    np.testing.assert_array_equal(dq, 0.0)
    tau1 = np.array([9.0, -1.0, 0.5])
    arm.write(tau1)
    np.testing.assert_array_equal(arm.tau, [4.0, -1.0, 0.5])  # clipped
    start = clock.t
    clock.t += 2.6 * P  # two whole periods and more than half of the third
    t, q, _ = arm.read()
    assert t == pytest.approx(2 * P)
    np.testing.assert_allclose(q, _by_hand(robot, q0, [arm.tau] * 2, P)[0], atol=1e-12)
    tau2 = np.array([0.0, 2.0, -5.0])
    arm.write(tau2)
    clock.t = start + 3 * P - 1e-15  # the third period ends (to rounding)
    assert int((clock.t - start) / P) == 2  # (what a plain division would make of it)
    t, q, dq = arm.read()
    assert t == pytest.approx(3 * P)
    expected = _by_hand(robot, q0, [np.clip(tau1, -4, 4)] * 2 + [np.clip(tau2, -4, 4)], P)
    np.testing.assert_allclose(q, expected[0], atol=1e-12)
    np.testing.assert_allclose(dq, expected[1], atol=1e-12)
    assert arm.writes == 2 and not arm.closed
    arm.close()
    assert arm.closed


def test_the_plant_arm_refuses_wrong_shapes(robot):
    plant = RK4Plant(robot.copy(), None, 0.001, 0.001)
    with pytest.raises(DimensionError):
        PlantArm(plant, np.zeros(2))
    with pytest.raises(DimensionError):
        PlantArm(plant, np.zeros(3), np.zeros(4))
    arm = PlantArm(plant, np.zeros(3))
    with pytest.raises(DimensionError, match=r"torque of shape \(2,\); expected \(3,\)"):
        arm.write(np.zeros(2))
    assert arm.writes == 0


# ------------------------------------------------------------- files and lines
def test_with_realtime_replaces_only_what_is_given():
    import hmpc_pin
    from hmpc_pin.apps.realtime import with_realtime

    from .conftest import CONFIGS

    config = hmpc_pin.load_config(CONFIGS / "panda_sine.toml")
    assert with_realtime(config) is config
    changed = with_realtime(config, rate=500.0, gc=False, priority=0, spin=1e-4)
    rc = changed.realtime
    assert (rc.rate, rc.gc, rc.priority, rc.spin) == (500.0, False, 0, 1e-4)
    assert rc.hold == config.realtime.hold


def test_nan_is_null_in_the_json_at_any_depth():
    from hmpc_pin.apps.realtime import _finite

    data = {"a": math.nan, "b": [1.0, math.inf, {"c": -math.inf}], "d": (2, math.nan), "e": "x"}
    assert _finite(data) == {"a": None, "b": [1.0, None, {"c": None}], "d": [2, None], "e": "x"}
    json.dumps(_finite(data), allow_nan=False)


def _result(t, err):
    from hmpc_pin.sim.result import Result

    n = err.shape[1]
    K = len(t)
    zeros = np.zeros((K, n))
    return Result(
        t=np.asarray(t), q=err.copy(), dq=zeros, tau=zeros, d=zeros, d_hat=zeros,
        q_ref=zeros, dq_ref=zeros, joint_names=["shoulder", "elbow"], meta={},
    )  # fmt: skip


def test_tracking_lines_are_rms_and_max_after_one_second():
    from hmpc_pin.apps.realtime import format_tracking, tracking_summary

    t = np.arange(0.0, 2.0 + 1e-9, 0.01)
    err = np.column_stack([np.where(t >= 1.0, 0.01, 5.0), np.where(t >= 1.0, -0.02, 5.0)])
    err[-1] = [0.03, -0.02]
    tr = tracking_summary(_result(t, err))
    late = err[t >= 1.0]
    assert tr["after"] == 1.0
    np.testing.assert_allclose(tr["rms_error"], np.sqrt((late**2).mean(axis=0)), rtol=1e-3)
    np.testing.assert_allclose(tr["max_error"], np.abs(late).max(axis=0), rtol=1e-12)
    lines = format_tracking(SimpleNamespace(result=_result(t, err))).splitlines()
    assert lines[0].split() == ["joint", "RMS", "e", "(t>=1s)", "[rad]", "max", "|e|", "[rad]"]
    assert lines[1].split()[0] == "shoulder" and lines[2].split()[0] == "elbow"
    assert float(lines[2].split()[2]) == pytest.approx(0.02, rel=1e-3)
    short = _result(t[t < 0.99], err[t < 0.99])
    assert tracking_summary(short) == {}
    assert format_tracking(SimpleNamespace(result=short)) == (
        "tracking: run shorter than 1 s, no metrics"
    )
