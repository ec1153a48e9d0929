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
