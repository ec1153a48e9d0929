"""Metrics: the chattering measures against closed forms and a time-domain computation."""

from __future__ import annotations

import numpy as np
import pytest

from hmpc_pin.apps.metrics import chattering


def test_total_variation_and_energy_share_of_known_signals():
    Ts, K = 0.01, 1000
    t = Ts * np.arange(K)  # 1 Hz and 20 Hz fall on exact DFT bins
    two_tones = np.sin(2 * np.pi * 1.0 * t) + 0.5 * np.sin(2 * np.pi * 20.0 * t)
    square = np.where(np.arange(K) % 2 == 0, 1.0, -1.0)  # switches every sample
    tv, share = chattering(t, np.column_stack([two_tones, square, np.full(K, 3.0)]))
    np.testing.assert_allclose(share[0], (0.5**2 / 2) / (1 / 2 + 0.5**2 / 2), rtol=1e-9)
    np.testing.assert_allclose(tv[1], 2.0 / Ts)  # a jump of 2 every sample
    np.testing.assert_allclose(share[1], 1.0)  # all of it at the 50 Hz Nyquist frequency
    assert tv[2] == 0 and share[2] == 0  # a constant torque does not chatter


def test_energy_share_equals_time_domain_energy_of_the_high_passed_signal(make_rng):
    rng = make_rng(1)
    Ts, K = 0.01, 501
    t = Ts * np.arange(K)
    x = rng.normal(size=(K, 2)) + np.linspace(0, 3, K)[:, None]
    _, share = chattering(t, x, cutoff=10.0)
    xc = x - x.mean(axis=0)
    spec = np.fft.rfft(xc, axis=0)
    spec[np.fft.rfftfreq(K, Ts) <= 10.0] = 0.0
    high = np.fft.irfft(spec, n=K, axis=0)
    np.testing.assert_allclose(share, (high**2).sum(axis=0) / (xc**2).sum(axis=0), rtol=1e-12)


def test_energy_share_of_an_even_length_record_with_a_nyquist_component(make_rng):
    """Even K: the Nyquist bin has no mirror and counts once (Parseval), checked against the
    time-domain energy of the high-passed signal on a record mixing low tones, noise and
    an alternating (Nyquist) part."""
    rng = make_rng(2)
    Ts, K = 0.01, 500
    t = Ts * np.arange(K)
    alt = np.where(np.arange(K) % 2 == 0, 1.0, -1.0)
    x = np.column_stack([np.sin(2 * np.pi * t) + 0.7 * alt, rng.normal(size=K) + 0.3 * alt])
    _, share = chattering(t, x, cutoff=10.0)
    xc = x - x.mean(axis=0)
    spec = np.fft.rfft(xc, axis=0)
    spec[np.fft.rfftfreq(K, Ts) <= 10.0] = 0.0
    high = np.fft.irfft(spec, n=K, axis=0)
    np.testing.assert_allclose(share, (high**2).sum(axis=0) / (xc**2).sum(axis=0), rtol=1e-12)
    # closed form for the first column: tone energy K/2, Nyquist part 0.7² K (exact bins)
    np.testing.assert_allclose(share[0], 0.49 / (0.5 + 0.49), rtol=1e-9)


def _hand_result(t, q, q_ref, d=None, d_hat=None, meta=None):
    import hmpc_pin

    q, q_ref = np.asarray(q, float), np.asarray(q_ref, float)
    zeros = np.zeros_like(q)
    d = zeros if d is None else np.asarray(d, float)
    d_hat = zeros if d_hat is None else np.asarray(d_hat, float)
    return hmpc_pin.Result(np.asarray(t, float), q, zeros, zeros, d, d_hat, q_ref, zeros,
                           meta=meta or {})  # fmt: skip


def test_settling_time_is_the_first_sample_after_the_last_exit():
    """Hand-built errors with known answers: the band is left last at sample 5, so the
    error stays inside from sample 6 on (t = 0.6 s), not from sample 5."""
    from hmpc_pin.apps.metrics import settling_time

    t = 0.1 * np.arange(10)
    e = np.array([0.5, 0.3, 0.0, 0.02, 0.0, 0.011, 0.005, 0.0, 0.001, 0.0])
    inside_always = np.full(10, 0.001)
    outside_at_end = e.copy()
    outside_at_end[-1] = 0.2
    st = settling_time(t, np.column_stack([e, inside_always, outside_at_end]), 0.01)
    assert st[0] == t[6] and st[1] == t[0] and np.isnan(st[2])
    # the definition, evaluated directly: every sample from st on is inside the band
    k = round(st[0] / 0.1)
    assert np.all(np.abs(e[k:]) < 0.01) and abs(e[k - 1]) >= 0.01


def test_observer_rms_is_taken_from_d_minus_d_hat_not_the_tracking_error():
    import hmpc_pin

    t = np.array([0.0, 1.0, 2.0, 3.0])
    d = np.array([[5.0], [3.0], [1.0], [2.0]])
    d_hat = np.array([[0.0], [2.0], [2.0], [2.0]])  # w = 5, 1, -1, 0
    q = np.array([[1.0], [0.5], [0.4], [0.3]])  # tracking error 1, .5, .4, .3 (q_ref = 0)
    m = hmpc_pin.compute_metrics(_hand_result(t, q, np.zeros((4, 1)), d, d_hat), after=1.0)
    np.testing.assert_allclose(m.observer_rms, [np.sqrt((1 + 1 + 0) / 3)])
    np.testing.assert_allclose(m.observer_peak, [1.0])
    np.testing.assert_allclose(m.rms_error, [np.sqrt((0.25 + 0.16 + 0.09) / 3)])


def test_limit_violation_counts_both_limits():
    """Joint a leaves its lower limit by 0.3, joint b its upper limit by 0.2, joint c stays
    inside: max distance outside [lower, upper]."""
    import hmpc_pin

    t = np.array([0.0, 0.5, 1.0])
    q = np.array([[-1.3, 0.0, 0.5], [-0.9, 1.2, -0.5], [0.0, 0.9, 0.0]])
    meta = {"limits": {"lower": [-1.0, -1.0, -1.0], "upper": [1.0, 1.0, 1.0]}}
    m = hmpc_pin.compute_metrics(_hand_result(t, q, np.zeros_like(q), meta=meta), after=0.0)
    np.testing.assert_allclose(m.limit_violation, [0.3, 0.2, 0.0], atol=1e-15)


# ------------------------------------------------- every field against numpy
def _random_result(make_rng, *, n=3, K=41, dt=0.05, meta=None, **arrays):
    """A hand-built run with random arrays, t = 0, dt, ..., (K-1) dt."""
    import hmpc_pin

    rng = make_rng(7)
    t = dt * np.arange(K)
    q, q_ref = rng.normal(size=(K, n)), rng.normal(size=(K, n))
    base = {name: rng.normal(size=(K, n)) for name in ("dq", "tau", "d", "d_hat", "dq_ref")}
    base.update(arrays)
    return hmpc_pin.Result(t, q, base["dq"], base["tau"], base["d"], base["d_hat"], q_ref,
                           base["dq_ref"], joint_names=tuple(f"j{i}" for i in range(n)),
                           meta=meta or {}, tau_applied=base.get("tau_applied"))  # fmt: skip


def test_every_metric_is_its_definition_on_its_window(make_rng):
    """after = 1.75 s falls exactly on a sample (it is in the window); errors, observer error,
    effort and chattering over t >= after, settling time and torque peaks over the whole
    run; a column of applied torque that is all NaN has no peak, NaN entries elsewhere
    are left out; the saturated periods and the position limits from the metadata."""
    from hmpc_pin.apps.metrics import compute_metrics

    K, n = 41, 3
    rng = make_rng(8)
    applied = rng.normal(size=(K, n))
    applied[:, 2] = np.nan
    applied[[0, 5], 1] = np.nan
    meta = {"saturation": {"steps": [0, 4, 1]},
            "limits": {"lower": [-0.5, -2.0, -1.0], "upper": [0.5, 2.0, 1.0]}}  # fmt: skip
    r = _random_result(make_rng, meta=meta, tau_applied=applied, dt=0.25)
    r.tau[0] = [50.0, -60.0, 70.0]  # the peaks are before the window
    m = compute_metrics(r, after=1.75, tol=0.8)
    keep = np.arange(K) >= 7
    assert r.t[7] == 1.75 and m.after == 1.75 and m.tol == 0.8
    e, w, tau = (r.q - r.q_ref)[keep], (r.d - r.d_hat)[keep], r.tau[keep]
    np.testing.assert_allclose(m.rms_error, np.sqrt((e**2).mean(axis=0)), rtol=1e-14)
    np.testing.assert_allclose(m.max_error, np.abs(e).max(axis=0), rtol=1e-14)
    np.testing.assert_allclose(m.observer_rms, np.sqrt((w**2).mean(axis=0)), rtol=1e-14)
    np.testing.assert_allclose(m.observer_peak, np.abs(w).max(axis=0), rtol=1e-14)
    np.testing.assert_allclose(m.tau_rms, np.sqrt((tau**2).mean(axis=0)), rtol=1e-14)
    np.testing.assert_array_equal(m.tau_peak, [50.0, 60.0, 70.0])
    tv, share = chattering(r.t[keep], tau)
    np.testing.assert_allclose(m.tau_tv, tv, rtol=1e-14)
    np.testing.assert_allclose(m.tau_hf_share, share, rtol=1e-14)
    np.testing.assert_allclose(m.tau_tv, np.abs(np.diff(tau, axis=0)).sum(0) / (10.0 - 1.75))
    peak = [np.abs(applied[:, 0]).max(), np.nanmax(np.abs(applied[:, 1]))]
    np.testing.assert_allclose(m.tau_applied_peak[:2], peak, rtol=1e-14)
    assert np.isnan(m.tau_applied_peak[2])
    np.testing.assert_array_equal(m.saturated_steps, [0, 4, 1])
    lo, hi = np.array([-0.5, -2.0, -1.0]), np.array([0.5, 2.0, 1.0])
    outside = np.maximum(np.maximum(lo - r.q, r.q - hi), 0.0).max(axis=0)
    np.testing.assert_allclose(m.limit_violation, outside, rtol=1e-14)
    assert outside[0] > 0  # the test's random angles do leave the narrow limits
    from hmpc_pin.apps.metrics import settling_time

    np.testing.assert_array_equal(m.settling_time, settling_time(r.t, r.q - r.q_ref, 0.8))
    assert m.task is None


def test_without_limits_or_saturation_records_the_metrics_say_so(make_rng):
    from hmpc_pin.apps.metrics import compute_metrics

    m = compute_metrics(_random_result(make_rng))
    assert np.all(np.isnan(m.limit_violation))
    np.testing.assert_array_equal(m.saturated_steps, [0, 0, 0])
    assert m.after == 1.0 and m.tol == 0.01  # the defaults


def test_the_band_edge_counts_as_outside():
    """|e| = tol is not within the band: the settling time is the sample after it."""
    from hmpc_pin.apps.metrics import settling_time

    t = np.arange(5.0)
    e = np.array([[0.3], [0.1], [0.05], [0.1], [0.0]])
    assert settling_time(t, e, 0.1)[0] == 4.0
    assert settling_time(t, e, 0.1 + 1e-12)[0] == 1.0
    assert settling_time(t, -e, 0.1)[0] == 4.0  # the magnitude, whatever the sign


# ------------------------------------------------------------- task space
def _quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([np.sin(angle / 2) * axis, [np.cos(angle / 2)]])


def test_task_metrics_are_distances_and_rotation_angles(make_rng):
    """Positions off by known vectors, orientations rotated by known angles about random
    axes (half of the quaternions in the other hemisphere: the same rotation); RMS and max
    over t >= after, the frame from the metadata."""
    from hmpc_pin.apps.metrics import task_metrics

    rng = make_rng(3)
    K = 21
    r = _random_result(make_rng, K=K, dt=0.25, meta={"task": {"frame": "tool0"}})
    r.ee_pos_ref = rng.normal(size=(K, 3))
    offset = rng.normal(size=(K, 3))
    r.ee_pos = r.ee_pos_ref + offset
    angles = rng.uniform(0.0, 3.0, K)
    ref = [_quat(rng.normal(size=3), a) for a in rng.uniform(0, 3, K)]
    r.ee_quat_ref = np.array(ref)
    rel = [_quat(rng.normal(size=3), a) for a in angles]

    # q = q_ref ⊗ rel (x, y, z, w), then every other one negated
    def mul(a, b):
        (x1, y1, z1, w1), (x2, y2, z2, w2) = a, b
        return np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                         w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
                         w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])  # fmt: skip

    r.ee_quat = np.array(
        [(-1) ** k * mul(a, b) for k, (a, b) in enumerate(zip(ref, rel, strict=True))]
    )
    tm = task_metrics(r, after=1.5)  # on a sample: t[6] = 1.5 is in the window
    keep = np.arange(K) >= 6
    dist = np.linalg.norm(offset[keep], axis=1)
    assert tm.position_rms == pytest.approx(np.sqrt((dist**2).mean()), rel=1e-12)
    assert tm.position_max == pytest.approx(dist.max(), rel=1e-12)
    assert tm.orientation_rms == pytest.approx(np.sqrt((angles[keep] ** 2).mean()), rel=1e-7)
    assert tm.orientation_max == pytest.approx(angles[keep].max(), rel=1e-7)
    assert tm.frame == "tool0"
    assert task_metrics(r, after=5.5) is None  # nothing after the end
    r.ee_pos = None
    assert task_metrics(r) is None


# ------------------------------------------------------------------- warnings
def test_run_warnings_threshold_window_and_saturation_line():
    """The tracking warning: max |e| over t >= after above the threshold (the threshold
    itself is not above it; NaN is); nothing on a run shorter than after. The saturation
    line: per saturated joint its periods of the run's, its commanded peak and limit."""
    import hmpc_pin
    from hmpc_pin.apps.metrics import run_warnings

    t = np.array([0.0, 0.5, 1.0, 1.5])
    q = np.array([[9.0, 0.0], [0.0, 9.0], [0.2, -0.1], [-0.3, 0.1]])
    z = np.zeros_like(q)
    tau = np.array([[1.0, -7.5], [2.0, 3.0], [0.5, 1.0], [0.0, 0.0]])

    def result(q, meta=None):
        return hmpc_pin.Result(t, q, z, tau, z, z, z, z, joint_names=("a", "b"),
                               meta=meta or {})  # fmt: skip

    assert run_warnings(result(q), error_threshold=0.3) == []  # 0.3 is not above 0.3
    lines = run_warnings(result(q), error_threshold=0.25)
    assert lines == ["tracking error exceeds 0.25 rad after 1 s: max |e| a 0.3 rad "
                     "(threshold: --warn-error)"]  # fmt: skip
    assert run_warnings(result(q), error_threshold=0.05, after=1.5) == [
        "tracking error exceeds 0.05 rad after 1.5 s: max |e| a 0.3 rad, b 0.1 rad "
        "(threshold: --warn-error)"]  # fmt: skip
    assert run_warnings(result(q), error_threshold=0.05, after=2.0) == []  # too short
    nan = q.copy()
    nan[3, 1] = np.nan
    assert "b nan rad" in run_warnings(result(nan), error_threshold=1.0)[0]
    sat = {"steps": [0, 2], "effort_limit": [5.0, 4.0]}
    lines = run_warnings(result(q, {"saturation": sat}), error_threshold=1.0)
    assert lines == ["torque saturated: b 2 of 3 periods (commanded peak 7.5 N·m, limit 4 N·m) "
                     "— the plant applied the clipped torque (tau_applied), not the "
                     "controller's"]  # fmt: skip


# ----------------------------------------------------------------- the table
def test_the_printed_table_holds_each_joints_metrics(make_rng):
    """format_metrics read back: each row's cells are the metrics of its joint; a prismatic
    joint's row and the headers say m and N."""
    from hmpc_pin.apps.metrics import compute_metrics, format_metrics

    meta = {"joint_kinds": ["revolute", "prismatic", "revolute"],
            "limits": {"lower": [-0.5, -2.0, -9.0], "upper": [0.5, 2.0, 9.0]},
            "saturation": {"steps": [3, 0, 12]}}  # fmt: skip
    r = _random_result(make_rng, meta=meta)
    r.q[:, 2] = r.q_ref[:, 2]  # joint 3 tracks exactly: within the band from t0
    r.q[-1, 1] = r.q_ref[-1, 1] + 1.0  # joint 2 outside the band at the end: never
    m = compute_metrics(r, after=0.5)
    text = format_metrics(m, r.joint_names, r)
    head, rule, *rows = text.splitlines()
    assert set(rule) == {"-"} and "RMS e (t>=0.5s) [rad|m]" in head and "[N·m|N]" in head
    names = ["j0", "j1 (m, N)", "j2"]
    for i, row in enumerate(rows):
        assert row.startswith(names[i])
        cells = row[len(names[i]) :].split()
        assert float(cells[0]) == pytest.approx(m.rms_error[i], rel=1e-3)
        assert float(cells[1]) == pytest.approx(m.max_error[i], rel=1e-3)
        st = {0: f"{m.settling_time[0]:.2f}", 1: "never", 2: "0.00"}[i]
        assert cells[2] == st
        assert float(cells[3]) == pytest.approx(m.observer_rms[i], rel=1e-3)
        assert float(cells[4]) == pytest.approx(m.tau_peak[i], abs=0.05)
        assert float(cells[5]) == pytest.approx(m.tau_applied_peak[i], abs=0.05)
        assert float(cells[6]) == pytest.approx(m.limit_violation[i], rel=0.05, abs=1e-12)
        assert int(cells[7]) == [3, 0, 12][i]
    plain = format_metrics(compute_metrics(_random_result(make_rng)))
    assert "[rad]" in plain and "[N·m]" in plain and "n/a" in plain  # no limits recorded
    assert plain.splitlines()[2].startswith("joint1")


def test_units_follow_the_joint_kinds(make_rng):
    from hmpc_pin.apps.metrics import joint_label, joint_units, unit_labels

    r = _random_result(make_rng, meta={"joint_kinds": ["prismatic", "revolute", "revolute"]})
    assert joint_units(r) == [("m", "m/s", "N"), *[("rad", "rad/s", "N·m")] * 2]
    assert unit_labels(r) == {"rad": "rad|m", "rad/s": "rad/s|m/s", "N·m": "N·m|N"}
    plain = _random_result(make_rng)
    assert unit_labels(plain) == {"rad": "rad", "rad/s": "rad/s", "N·m": "N·m"}
    assert joint_label("slide", ("m", "m/s", "N")) == "slide (m, N)"
    assert joint_label("hinge", ("rad", "rad/s", "N·m")) == "hinge"


def test_contact_and_collision_lines(make_rng):
    """The contact line names the joint of the largest peak contact force and its unit;
    the collision line when, where and the joint's threshold."""
    from hmpc_pin.apps.metrics import contact_lines

    meta = {"joint_kinds": ["revolute", "prismatic", "revolute"], "first_contact": 0.25,
            "collision": {"detected_at": 1.5, "joint": "j1", "threshold": [3.0, 4.5, 6.0],
                          "reaction": "stop"}}  # fmt: skip
    r = _random_result(make_rng, meta=meta)
    force = np.zeros((41, 3))
    force[10] = [5.0, -8.0, 7.0]  # the largest magnitude on j1, negative
    r.extra["contact_force"] = force
    assert contact_lines(r) == [
        "contact: first at t = 0.250 s with the obstacle; peak generalized contact force 8 N at j1",
        "collision: flagged at t = 1.500 s on j1 (|d_hat| above its threshold 4.5 N); "
        "reaction: stop",
    ]
    quiet = _random_result(make_rng, meta={"first_contact": None,
                                           "collision": {"detected_at": None}})  # fmt: skip
    assert contact_lines(quiet) == [
        "contact: the arm never touched the obstacle",
        "collision: none flagged (|d_hat| stayed below the threshold)",
    ]
    assert contact_lines(_random_result(make_rng)) == []
