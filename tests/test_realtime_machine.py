"""``hmpc_pin.realtime.machine``: other processes' real-time threads, found in ``/proc``
and checked against the scheduler's own answer (``os.sched_getscheduler``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.realtime.machine import PF_KTHREAD, realtime_rivals, rival_warnings, steal_time

from .test_cli_realtime import _config

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux /proc")

# A child that takes SCHED_FIFO at the priority given (or says it may not), then sleeps.
_CHILD = """
import os, sys, time
prio = int(sys.argv[1])
try:
    if prio:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
    print("ok", flush=True)
except OSError:
    print("refused", flush=True)
time.sleep(60)
"""


@pytest.fixture
def child():
    """Start sleeping children (``child(priority)``: 0 = normal policy); killed after."""
    procs: list[subprocess.Popen] = []

    def start(priority: int) -> subprocess.Popen:
        proc = subprocess.Popen(
            [sys.executable, "-c", _CHILD, str(priority)], stdout=subprocess.PIPE, text=True
        )
        procs.append(proc)
        assert proc.stdout is not None
        if proc.stdout.readline().strip() != "ok":
            pytest.skip("this process may not set SCHED_FIFO (no CAP_SYS_NICE/rtprio limit)")
        return proc

    yield start
    for proc in procs:
        proc.kill()
        proc.wait()


def test_a_fifo_process_is_found_with_its_policy_and_priority(child):
    proc = child(7)
    mine = [r for r in realtime_rivals() if r.pid == proc.pid]
    assert mine, "the SCHED_FIFO child was not found"
    # the scheduler's own answer for the same process
    assert os.sched_getscheduler(proc.pid) == os.SCHED_FIFO
    assert {(r.policy, r.priority) for r in mine} == {
        ("SCHED_FIFO", os.sched_getparam(proc.pid).sched_priority)
    }
    assert mine[0].name == Path(f"/proc/{proc.pid}/comm").read_text().strip()


def test_a_normal_process_and_the_excluded_ones_are_not(child):
    normal, fifo = child(0), child(5)
    pids = {r.pid for r in realtime_rivals()}
    assert normal.pid not in pids and fifo.pid in pids
    assert fifo.pid not in {r.pid for r in realtime_rivals(exclude=[fifo.pid])}
    assert os.getpid() not in pids


def test_no_kernel_thread_and_none_of_this_process_is_listed():
    """Against the scheduler and ``status``: the kernel's own real-time threads (no memory
    map: no ``VmSize``) are never listed, nor this process's; every thread listed is a
    user thread (robust to a concurrent suite: kernel threads never become user ones)."""
    kernel = set()
    for task in Path("/proc").glob("[0-9]*/task/[0-9]*"):
        try:
            policy = os.sched_getscheduler(int(task.name))
            status = (task / "status").read_text()
        except OSError:
            continue
        if policy in (os.SCHED_FIFO, os.SCHED_RR) and "VmSize:" not in status:
            kernel.add(int(task.name))
    found = realtime_rivals()
    assert not ({r.tid for r in found} & kernel)
    assert os.getpid() not in {r.pid for r in found}
    for rival in found:
        try:
            status = Path(f"/proc/{rival.pid}/status").read_text()
        except OSError:
            continue  # ended since
        assert "VmSize:" in status, rival


def test_a_stat_line_with_parentheses_in_its_name_is_read(tmp_path):
    """``comm`` may hold spaces and ')' (proc(5)): fields are counted from its last ')'."""
    fields = ["S"] + ["0"] * 50
    fields[9 - 3] = str(0x400000)  # flags (field 9): a user thread
    fields[40 - 3], fields[41 - 3] = "42", "2"  # rt_priority, policy SCHED_RR
    task = tmp_path / "4242" / "task" / "4243"
    task.mkdir(parents=True)
    (task / "stat").write_text(f"4243 (my (odd) name) {' '.join(fields)}\n")
    kthread = tmp_path / "7" / "task" / "7"
    kthread.mkdir(parents=True)
    kfields = list(fields)
    kfields[9 - 3] = str(PF_KTHREAD)
    (kthread / "stat").write_text(f"7 (migration/0) {' '.join(kfields)}\n")
    (rival,) = realtime_rivals(proc=tmp_path)
    assert (rival.pid, rival.tid, rival.name, rival.policy, rival.priority) == (
        4242,
        4243,
        "my (odd) name",
        "SCHED_RR",
        42,
    )
    (line,) = rival_warnings(proc=tmp_path)
    assert line.startswith("process 4242 (my (odd) name) runs under SCHED_RR 42:")


def test_realtime_warns_of_a_real_time_process_before_its_run(tmp_path, capsys, child):
    """The warning before the run; and the run's record of the host's steal time lies
    within the steal counted around the whole command."""
    proc = child(3)
    cfg = _config(tmp_path)
    before = steal_time()
    assert main(["realtime", str(cfg), "--duration", "0.3", "--out", str(tmp_path)]) == 0
    after = steal_time()
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith(f"warning: process {proc.pid} ")]
    assert len(lines) == 1 and "SCHED_FIFO 3" in lines[0] and "separate CPUs" in lines[0]
    stats = json.loads((tmp_path / "rt_realtime.json").read_text())["realtime"]
    assert 0.0 <= stats["host_steal_s"] <= after - before


def test_steal_time_is_the_eighth_cpu_field_in_seconds(tmp_path):
    tick = os.sysconf("SC_CLK_TCK")
    stat = tmp_path / "stat"
    stat.write_text("cpu  10 20 30 40 50 60 70 250 0 0\ncpu0 5 10 15 20 25 30 35 125 0 0\n")
    assert steal_time(stat) == 250 / tick
    stat.write_text("cpu  10 20 30 40\n")  # an old kernel: no steal column
    assert steal_time(stat) == 0.0
    assert steal_time(tmp_path / "absent") == 0.0
    # the machine's own: its first line's eighth number, never decreasing
    first = Path("/proc/stat").read_text().splitlines()[0].split()
    now = steal_time()
    assert now >= int(first[8]) / tick and steal_time() >= now
