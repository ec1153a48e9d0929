"""Metrics: the chattering measures against closed forms and a time-domain computation."""

from __future__ import annotations

import numpy as np

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
