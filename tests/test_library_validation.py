"""The library refuses, when an object is built, what the config loader refuses, with the
same typed errors (:mod:`hmpc_pin.checks` is the one place of both checks)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin import (
    ComputedTorque,
    ConfigError,
    ControllerConfig,
    DimensionError,
    DisturbanceObserver,
    EulerPlant,
    HierarchicalMPC,
    MPCSettings,
    RK4Plant,
    SimulationError,
    SineReference,
    ValidityWarning,
)

from .test_urdf_joints import three_links


# ------------------------------------------------------------------ MPCSettings
@pytest.mark.parametrize(
    ("kwargs", "key", "text"),
    [
        ({"R": -1.0}, "R", "expected a number > 0, got -1.0"),
        ({"R": 0.0}, "R", "expected a number > 0, got 0.0"),
        ({"N": 0}, "N", "expected an integer >= 1, got 0"),
        ({"N": 3, "Nc": 4}, "Nc", "expected 1 <= Nc <= N"),
        ({"Ts": -0.01}, "Ts", "expected a number > 0, got -0.01"),
        ({"Ts": 0.0}, "Ts", "expected a number > 0, got 0.0"),
        ({"v_min": 5.0, "v_max": -5.0}, "v_min", "must be < v_max"),
        ({"Q": [[1.0, 0.0], [0.0, -1.0]]}, "Q", "positive semi-definite"),
        ({"max_iter": 0}, "max_iter", "expected an integer >= 1"),
        ({"qp_layout": "rows"}, "qp_layout", "expected one of"),
    ],
)
def test_mpc_settings_refuse_what_the_config_refuses(kwargs, key, text):
    with pytest.raises(ConfigError, match=f"^MPCSettings.{key}: ") as lib:
        MPCSettings(**kwargs)
    assert lib.value.key == f"MPCSettings.{key}" and text in lib.value.message
    if key in ("max_iter", "qp_layout"):
        return  # [controller] checks these too, with its other defaults
    with pytest.raises(ConfigError) as cfg:
        ControllerConfig(**kwargs)
    assert cfg.value.key == key and cfg.value.message == lib.value.message


def test_mpc_settings_boundaries():
    """Nc = N is a valid horizon; equal bounds leave no acceleration to choose."""
    assert MPCSettings(N=4, Nc=4).Nc == 4
    with pytest.raises(ConfigError, match=r"v_min: .* must be < v_max"):
        MPCSettings(v_min=[-1.0, 2.0, -1.0], v_max=[1.0, 2.0, 1.0])
    with pytest.raises(ConfigError, match="v_max: v_min has shape"):
        MPCSettings(v_min=[-1.0, -1.0], v_max=[1.0, 1.0, 1.0])
    with pytest.raises(ConfigError, match="Ts: expected a finite number"):
        MPCSettings(Ts=float("nan"))


def test_mpc_settings_per_joint_bounds_of_the_wrong_length(planar3):
    settings = MPCSettings(v_min=[-1.0, -1.0], v_max=[1.0, 1.0])
    with pytest.raises(ConfigError, match=r"MPCSettings\.v_min: has 2 entries but the robot has 3"):
        HierarchicalMPC(planar3, settings)


def test_valid_settings_are_kept(planar3):
    s = MPCSettings(Ts=0.005, N=12, Nc=3, R=1e-4, v_min=[-1, -2, -3], v_max=3)
    assert (s.Ts, s.N, s.Nc, s.R) == (0.005, 12, 3, 1e-4)
    assert HierarchicalMPC(planar3, s).settings.bounds(3)[0].tolist() == [-1.0, -2.0, -3.0]


# ------------------------------------------------------------------ compensation
def test_observer_for_another_number_of_joints_is_refused(planar3):
    observer = DisturbanceObserver(2, 0.01, 100.0, "general")
    with pytest.raises(DimensionError, match=r"estimates \(2,\) torques but robot .* has 3"):
        HierarchicalMPC(planar3, MPCSettings(), observer)
    with pytest.raises(DimensionError, match="has 3 joints"):
        ComputedTorque(planar3, None, observer)


def test_observer_with_another_period_is_refused(planar3):
    observer = DisturbanceObserver(3, 0.005, 100.0, "general")
    words = r"period 0\.005 s differs from the controller's Ts = 0\.01"
    with pytest.raises(ConfigError, match=words):
        HierarchicalMPC(planar3, MPCSettings(Ts=0.01), observer)


def test_default_observer_on_a_spatial_arm_warns_as_the_config_does(write_urdf, planar3):
    spatial = hmpc_pin.load_robot(write_urdf(three_links(j1={"axis": "0 0 1"})))
    with pytest.warns(ValidityWarning, match="compensation = 'general'"):
        HierarchicalMPC(spatial)
    with pytest.warns(ValidityWarning, match="proven for planar serial arms only"):
        ComputedTorque(spatial, None, DisturbanceObserver(3, 0.01, 100.0, "chen"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ValidityWarning)
        HierarchicalMPC(planar3)  # the paper's planar arm: no warning
        HierarchicalMPC(spatial, MPCSettings(), DisturbanceObserver(3, 0.01, 100.0, "general"))


# ------------------------------------------------------------------ references, order
def test_reference_for_another_number_of_joints_is_refused(planar3):
    ctrl = HierarchicalMPC(planar3)
    ctrl.reset(np.zeros(3), np.zeros(3))
    with pytest.raises(DimensionError, match="is for 7 joints but the robot has 3"):
        ctrl.step(0.0, np.zeros(3), np.zeros(3), SineReference(7))
    ct = ComputedTorque(planar3)
    ct.reset(np.zeros(3), np.zeros(3))
    with pytest.raises(DimensionError, match="is for 2 joints but the robot has 3"):
        ct.step(0.0, np.zeros(3), np.zeros(3), SineReference(2))


@pytest.mark.parametrize("cls", [HierarchicalMPC, ComputedTorque])
def test_controller_step_before_reset_is_refused(planar3, cls):
    ctrl = cls(planar3)
    with pytest.raises(SimulationError, match="step before reset: call reset"):
        ctrl.step(0.0, np.zeros(3), np.zeros(3), SineReference(3))
    ctrl.reset(np.zeros(3), np.zeros(3))
    assert ctrl.step(0.0, np.zeros(3), np.zeros(3), SineReference(3)).shape == (3,)


def _plants(robot):
    yield RK4Plant(robot, None, 0.01, 0.001)
    yield EulerPlant(robot, None, 0.01, 0.001)
    mujoco = pytest.importorskip("mujoco")
    assert mujoco
    yield hmpc_pin.MuJoCoPlant(robot, None, 0.01, 0.001)


def test_plant_advance_before_reset_and_with_a_wrong_torque_is_refused(planar3):
    for plant in _plants(planar3):
        name = type(plant).__name__
        with pytest.raises(SimulationError, match=f"{name}.advance before reset"):
            plant.advance(np.zeros(3))
        plant.reset(np.zeros(3), np.zeros(3))
        with pytest.raises(DimensionError, match=r"torque of shape \(2,\); expected \(3,\)"):
            plant.advance(np.zeros(2))
        with pytest.raises(DimensionError, match=r"torque of shape \(\); expected \(3,\)"):
            plant.advance(0.0)
        q, dq = plant.advance(np.zeros(3))
        assert q.shape == dq.shape == (3,) and plant.t == pytest.approx(0.01)


# ------------------------------------------------------------------ the converters
def test_a_latency_is_refused_just_past_its_bound_and_kept_at_it():
    """:func:`~hmpc_pin.checks.as_latency`: [0, MAX_LATENCY] s, both ends kept; the next
    float above the bound, 1.5 s and a negative age are refused naming the key."""
    import math

    from hmpc_pin.checks import MAX_LATENCY, as_latency

    assert as_latency("controller.latency", 0) == 0.0
    assert as_latency("controller.latency", MAX_LATENCY) == MAX_LATENCY
    for bad in (math.nextafter(MAX_LATENCY, math.inf), 1.5 * MAX_LATENCY, -1e-3):
        with pytest.raises(ConfigError) as info:
            as_latency("controller.latency", bad)
        assert info.value.key == "controller.latency"


@pytest.mark.parametrize(
    ("weight", "text"),
    [
        ([0.0, 0.0], "non-zero"),  # PSD, but weighs nothing
        ([[0.0, 0.0], [0.0, 0.0]], "non-zero"),
        ([[1.0, 2.0], [2.0, 1.0]], "positive semi-definite"),  # eigenvalues 3 and -1
        ([[1.0, 0.5], [0.0, 1.0]], "symmetric"),  # eigenvalues 1, 1 but not symmetric
        ([1.0, -1e-3], "positive semi-definite"),
    ],
)
def test_a_weight_that_is_not_a_psd_nonzero_matrix_is_refused(weight, text):
    """:func:`~hmpc_pin.checks.as_weight` against the definition: symmetric, eigenvalues
    (numpy's, of the matrix given) >= 0 and not all 0."""
    from hmpc_pin.checks import as_weight

    with pytest.raises(ConfigError, match=text):
        as_weight("controller.Q", weight)


@pytest.mark.parametrize("weight", [[1.0, 0.0], [[2.0, 1.0], [1.0, 0.5]], [[1e-12, 0], [0, 0]]])
def test_a_singular_psd_weight_is_kept(weight):
    """Singular but PSD and non-zero (eigenvalues of [[2, 1], [1, 0.5]]: 2.5 and 0)."""
    from hmpc_pin.checks import as_weight

    arr = np.asarray(weight, dtype=float)
    out = as_weight("controller.Q", weight)
    np.testing.assert_array_equal(out, np.diag(arr) if arr.ndim == 1 else arr)


def test_one_negative_entry_of_a_nonnegative_vector_is_refused():
    """:func:`~hmpc_pin.checks.as_array` with ``nonneg``: any entry below 0, not only all."""
    from hmpc_pin.checks import as_array

    np.testing.assert_array_equal(as_array("b", [0.0, 2.0], nonneg=True), [0.0, 2.0])
    with pytest.raises(ConfigError, match=">= 0"):
        as_array("b", [1.0, -1.0], nonneg=True)
    with pytest.raises(ConfigError, match="> 0"):
        as_array("b", [1.0, 0.0], positive=True)
