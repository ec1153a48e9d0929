"""The status line of a running loop: :meth:`RealtimeLoop.progress` read mid-run (from the
controller's step, as another thread would read it) against the run's own records after
it, and :class:`~hmpc_pin.apps.realtime.StatusLine` printing it from its thread."""

from __future__ import annotations

import io
import math
import time

import numpy as np
import pytest

from hmpc_pin.apps.realtime import StatusLine, format_status

from .test_realtime import P, _setup


@pytest.fixture(scope="module")
def robot(planar3):
    return planar3


def test_progress_mid_run_is_what_the_records_say_after_it(robot):
    """At the controller step of t = 0.3 s (cycle 300 running): 300 cycles done, the
    misses so far (3.5 periods of compute once at 0.2 s: 3 missed), the tracking error of
    the last recorded step (t = 0.29 s), and the worst latency of the cycles since the
    previous call."""
    seen = {}
    holder = {}

    def hook(t):
        if abs(t - 0.1) < 1e-9:
            seen[0.1] = holder["loop"].progress()
        if abs(t - 0.3) < 1e-9:
            seen[0.3] = holder["loop"].progress()

    cost = lambda t: 3.5 * P if abs(t - 0.2) < 1e-9 else 0.0  # noqa: E731
    loop, _, _, _ = _setup(robot, 0.5, cost=cost, hook=hook)
    holder["loop"] = loop
    assert loop.progress() is None  # before the first cycle
    run = loop.run()
    p = seen[0.3]
    r = run.result
    j = int(np.flatnonzero(np.isclose(r.t, 0.29))[0])
    assert p["t"] == pytest.approx(0.29)
    assert p["error"] == pytest.approx(float(np.abs(r.q[j] - r.q_ref[j]).max()), rel=1e-12)
    ran = np.isfinite(run.timing["latency"][:300])
    assert p["cycles"] == int(ran.sum()) == 300 - 2  # (two deadlines skipped)
    assert p["misses"] == 3 and p["longest"] == 3
    assert p["of"] == round(0.5 / P) + 1
    # the worst latency since the call at 0.1 s: the 3.5-period cycle at 0.2 s
    window = run.timing["latency"][100:300]
    assert p["worst_us"] == pytest.approx(1e6 * np.nanmax(window))
    assert p["worst_us"] == pytest.approx(1e6 * 3.5 * P)


def test_the_status_line_is_printed_by_its_thread():
    class Loop:
        calls = 0

        def progress(self):
            Loop.calls += 1
            return {"t": 5.0, "cycles": 5001, "of": 60001, "misses": 12, "longest": 3,
                    "worst_us": 812.4, "error": 1.21e-3}  # fmt: skip

    out = io.StringIO()
    status = StatusLine(Loop(), 60.0, every=0.01, file=out)
    end = time.monotonic() + 10.0
    while status.lines < 2 and time.monotonic() < end:
        time.sleep(0.01)
    status.close()
    lines = out.getvalue().splitlines()
    assert len(lines) >= 2
    assert lines[0] == (
        "t=5.0 s of 60 s: 5001 cycles, 12 missed (longest run 3), worst latency 812 us "
        "since the last line, max |q - q_ref| 1.21e-03 rad"
    )
    nan = {"t": 0.0, "cycles": 1, "of": 2, "misses": 0, "longest": 0, "worst_us": math.nan,
           "error": math.nan}  # fmt: skip
    assert "worst latency - since" in format_status(nan, 1.0)
