"""Where the ROS node's measurement → torque time goes: ``hmpc-pin ros-arm`` and
``hmpc-pin ros`` on one machine, every state and command timed on the system clock.

Run inside a private network namespace only (DDS discovery multicasts; the study refuses
to run where another interface than ``lo`` is up):

    unshare -n bash -c 'ip link set lo up; python benchmarks/studies/ros_latency.py \
        [--config panda_sine] [--duration 5] [--runs 3] [--variants default,messages,arm-sleep]'

Each run starts the arm node and the controller node as ``hmpc-pin ros-arm`` and
``hmpc-pin ros --duration D`` would (``--priority 50`` both; the same code, run through
this file so that each process also records its messages' times), one variant after the
other in alternating order (the controller with ``--max-misses 1000000``: a loaded
machine's run goes to its end). A variant is a set of environment variables given to both
processes (``VARIANTS``: the middleware's own, or this study's switches of the nodes'
code paths, ``ROS_LATENCY_*``). Per state, with the arm's stamp s (the period's instant):

* **arm: stamp → wake**, **wake → command taken**, **command taken → publish call** (its
  plant step and the message filled) and **the publish call** itself;
* **DDS: publish → reception**: from the call to the controller's middleware reception
  time stamp (the state's *arrival*);
* **arrival → wake**: from the arrival to the controller's loop holding the state (the
  wait set's wake-up, the take and the merge); **wake → torque published**: the step and
  the publish call;
* **(a) arrival → torque published**: the controller node's own share (the loop's
  ``latency``, its deadline being the arrival);
* **stamp → torque published**: what ``stats["measured_latency"]`` reports;
* **DDS: torque publish → arm reception** and **(b) stamp → torque received by the arm**
  (the arm's middleware reception time of the command answering state s, matched by the
  command's source time stamp).

Prints one Markdown table per variant (median and p99 [µs] over every cycle of its runs),
and the per-run medians of (a) and (b).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]

#: The environment variables of each variant (``None``: removed).
VARIANTS: dict[str, dict[str, str | None]] = {
    "default": {},
    "async": {"RMW_FASTRTPS_PUBLICATION_MODE": "ASYNCHRONOUS"},
    "sync": {"RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS"},
    "udp": {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"},
    "shm": {"FASTDDS_BUILTIN_TRANSPORTS": "SHM"},
    # the arm node sleeps until each period (no busy-wait of the last stretch)
    "arm-sleep": {"ROS_LATENCY_ARM_SLEEP": "1"},
    # the controller polls its wait set from 300 µs before the next state is due
    "ctrl-spin": {"ROS_LATENCY_CTRL_SPIN": "0.0003"},
    # the joint states and commands taken as Python messages (rclpy's conversion)
    "messages": {"ROS_LATENCY_MESSAGES": "1"},
}


def _private_namespace() -> bool:
    """Whether the loopback is the only network interface (a private namespace;
    ``/proc/net/dev`` lists the calling process's namespace)."""
    lines = Path("/proc/net/dev").read_text().splitlines()[2:]
    return [line.split(":")[0].strip() for line in lines] == ["lo"]


# ------------------------------------------------------------------ the two processes
def _take_messages() -> None:
    """Subscriptions taken as Python messages (rclpy's conversion), as before the nodes
    took them serialized (the variant ``messages``)."""
    from hmpc_pin.ros.node import RosNode

    subscribe = RosNode.subscribe

    def converted(self, msg_type, topic, qos, raw=False):
        return subscribe(self, msg_type, topic, qos)

    RosNode.subscribe = converted  # type: ignore[method-assign]


def _arm_role(argv: list[str], out: Path) -> int:
    """``hmpc-pin ros-arm`` recording each state's publish call and each command's
    middleware times."""
    from hmpc_pin.apps.cli import main
    from hmpc_pin.ros import arm as arm_module

    if os.environ.get("ROS_LATENCY_MESSAGES"):  # commands taken as Python messages
        _take_messages()
        arm_module.read_float64_array = lambda msg: msg.data  # type: ignore[assignment]
    if os.environ.get("ROS_LATENCY_ARM_SLEEP"):  # the arm sleeps the whole wait
        arm_module.realtime_policy = lambda: False  # type: ignore[assignment]
    wakes: list[float] = []
    took: list[float] = []
    pubs: list[tuple[float, float, float]] = []
    cmds: list[tuple[float, float, float]] = []
    cls = arm_module.RosArmNode
    publish = cls._publish

    def timed_publish(self, stamp: float) -> None:
        t1 = time.time()
        publish(self, stamp)
        pubs.append((stamp, t1, time.time()))

    from hmpc_pin.ros.node import RosNode

    def recorded_take(sub) -> list:
        # RosNode.take, recording each command's middleware times
        out = []
        with sub.handle:
            while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                msg, info = got
                cmds.append(
                    (
                        1e-9 * info["received_timestamp"],
                        1e-9 * info["source_timestamp"],
                        time.time(),
                    )
                )
                out.append(msg)
        return out

    take_command = cls._take_command

    def timed_take(self) -> None:
        wakes.append(time.time())
        take_command(self)
        took.append(time.time())

    cls._publish = timed_publish  # type: ignore[method-assign]
    cls._take_command = timed_take  # type: ignore[method-assign]
    RosNode.take = staticmethod(recorded_take)  # type: ignore[method-assign]
    try:
        return main(argv)
    finally:
        np.savez(
            out,
            pubs=np.array(pubs).reshape(-1, 3),
            cmds=np.array(cmds).reshape(-1, 3),
            wakes=np.array(wakes),
            took=np.array(took),
        )


def _controller_role(argv: list[str], out: Path) -> int:
    """``hmpc-pin ros`` recording each complete state's stamp and arrival."""
    from hmpc_pin.apps.cli import main
    from hmpc_pin.ros import interface

    states: list[tuple[float, float]] = []
    origin: list[float] = []
    cls = interface.RosArmInterface
    on_state = cls._on_state

    def timed_on_state(self, msg, received: float) -> None:
        st = msg.header.stamp
        states.append((st.sec + 1e-9 * st.nanosec, received))
        on_state(self, msg, received)
        if not origin and self._based:
            origin.append(self.origin)

    cls._on_state = timed_on_state  # type: ignore[method-assign]
    if os.environ.get("ROS_LATENCY_MESSAGES"):
        _take_messages()
        interface.JointStateReader = lambda: lambda msg: msg  # type: ignore[assignment]
    spin = float(os.environ.get("ROS_LATENCY_CTRL_SPIN", "0"))
    if spin > 0:
        wait = cls.wait

        def spinning_wait(self, timeout: float) -> int:
            # block until spin before the next state is due, then poll the wait set
            if self._latest is not None and not self._arrivals:
                due = self._latest[3] + self.period - spin  # arrival [s] on clock()
                block = due - self.clock()
                if block > 0:
                    self._wait(min(block, timeout))
                    self._poll()
                end = time.monotonic() + 2 * spin
                while not self._arrivals and time.monotonic() < end:
                    self._wait(0.0)
                    self._poll()
            return wait(self, timeout)

        cls.wait = spinning_wait  # type: ignore[method-assign]
    try:
        return main(argv)
    finally:
        np.savez(out, states=np.array(states).reshape(-1, 2), origin=np.array(origin[:1]))


# ------------------------------------------------------------------------ one run
def one_run(config: str, duration: float, env: dict[str, str | None], work: Path) -> dict:
    """Both nodes once; returns the per-cycle segments [s] (module doc)."""
    environ = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    for key, value in env.items():
        if value is None:
            environ.pop(key, None)
        else:
            environ[key] = value
    me = [sys.executable, str(Path(__file__).resolve())]
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.PIPE, "env": environ}
    arm = subprocess.Popen(
        [*me, "--role", "arm", "--record", str(work / "arm.npz"), "--",
         "ros-arm", config, "--priority", "50"], **quiet)  # fmt: skip
    ctrl = subprocess.run(
        [*me, "--role", "controller", "--record", str(work / "ctrl.npz"), "--",
         "ros", config, "--duration", str(duration), "--out", str(work), "--force",
         "--priority", "50", "--max-misses", "1000000"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=environ, text=True,
        check=False)  # fmt: skip
    arm.send_signal(2)
    _, arm_err = arm.communicate(timeout=30)
    if ctrl.returncode != 0:
        raise RuntimeError(
            f"hmpc-pin ros failed ({ctrl.returncode}): {ctrl.stderr[-2000:]}\n"
            f"the arm node: {arm_err.decode()[-2000:]}"
        )
    return segments(work, config)


def segments(work: Path, config: str) -> dict[str, np.ndarray]:
    """The per-cycle segments of one run from its three records (module doc)."""
    a, c = np.load(work / "arm.npz"), np.load(work / "ctrl.npz")
    timing = np.load(work / f"{config}_ros_timing.npz")
    pubs, cmds, states = a["pubs"], a["cmds"], c["states"]
    origin = float(c["origin"][0])
    ok = np.isfinite(timing["stamp"])
    stamp = timing["stamp"][ok] + origin  # the stamp of the state each cycle answered
    latency, wake, compute = timing["latency"][ok], timing["wake"][ok], timing["compute"][ok]

    def lookup(keys: np.ndarray, table: np.ndarray, at: np.ndarray, tol: float) -> np.ndarray:
        """``table[i]`` where ``keys[i]`` is nearest each ``at`` (NaN beyond ``tol``)."""
        order = np.argsort(keys)
        keys, table = keys[order], table[order]
        i = np.clip(np.searchsorted(keys, at), 1, len(keys) - 1)
        j = np.where(np.abs(keys[i - 1] - at) < np.abs(keys[i] - at), i - 1, i)
        return np.where(np.abs(keys[j] - at) <= tol, table[j], np.nan)

    t_pub = lookup(pubs[:, 0], pubs[:, 1], stamp, 2e-6)
    # the arm's wake before publishing each state: the last wake before its publish call
    wakes = np.sort(a["wakes"])
    w = np.searchsorted(wakes, t_pub, side="right") - 1
    t_wake = np.where(w >= 0, wakes[np.maximum(w, 0)], np.nan)
    t_taken = np.where(w >= 0, a["took"][np.argsort(a["wakes"])][np.maximum(w, 0)], np.nan)
    t_pub_end = lookup(pubs[:, 0], pubs[:, 2], stamp, 2e-6)
    received = lookup(states[:, 0], states[:, 1], stamp, 2e-6)
    published = received + latency  # the controller's torque published [s]
    # the command answering each cycle: the one whose source time stamp (set in the
    # controller's publish call) is the last before the cycle's publish call returned
    src, arm_rx = cmds[:, 1], cmds[:, 0]
    order = np.argsort(src)
    src, arm_rx = src[order], arm_rx[order]
    k = np.searchsorted(src, published, side="right") - 1
    valid = (k >= 0) & (published - src[np.maximum(k, 0)] < 3e-4)
    cmd_rx = np.where(valid, arm_rx[np.maximum(k, 0)], np.nan)
    cmd_src = np.where(valid, src[np.maximum(k, 0)], np.nan)
    return {
        "arm: stamp → wake": t_wake - stamp,
        "arm: wake → command taken": t_taken - t_wake,
        "arm: command taken → publish call (plant step)": t_pub - t_taken,
        "arm: publish call": t_pub_end - t_pub,
        "DDS: publish → reception (arrival)": received - t_pub,
        "controller: arrival → wake": wake,
        "controller: wake → torque published": compute,
        "(a) controller: arrival → torque published": latency,
        "stamp → torque published": published - stamp,
        "DDS: torque publish → arm reception": cmd_rx - cmd_src,
        "(b) stamp → torque received by the arm": cmd_rx - stamp,
    }


def table(name: str, runs: list[dict]) -> str:
    """A Markdown table of the variant's segments over all its runs."""
    lines = [f"**{name}** ({len(runs)} runs)", "", "| [µs] | median | p99 |", "|---|---:|---:|"]
    for key in runs[0]:
        x = np.concatenate([r[key] for r in runs])
        x = x[np.isfinite(x)]
        lines.append(f"| {key} | {1e6 * np.median(x):.0f} | {1e6 * np.percentile(x, 99):.0f} |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="panda_sine")
    parser.add_argument("--duration", type=float, default=5.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--variants", default="default,messages,arm-sleep")
    parser.add_argument("--json", type=Path, help="write the medians here too")
    parser.add_argument("--role", choices=("arm", "controller"), help=argparse.SUPPRESS)
    parser.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    args, rest = parser.parse_known_args()
    if args.role == "arm":
        return _arm_role([x for x in rest if x != "--"], args.record)
    if args.role == "controller":
        return _controller_role([x for x in rest if x != "--"], args.record)
    if not _private_namespace():
        print(
            "run inside a private network namespace: unshare -n bash -c 'ip link set lo up; "
            "python benchmarks/studies/ros_latency.py ...'",
            file=sys.stderr,
        )
        return 2
    names = args.variants.split(",")
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        print(f"unknown variants {unknown}; expected some of {list(VARIANTS)}", file=sys.stderr)
        return 2
    results: dict[str, list[dict]] = {n: [] for n in names}
    print(f"load average before: {os.getloadavg()}")
    for r in range(args.runs):
        for name in names if r % 2 == 0 else names[::-1]:
            with tempfile.TemporaryDirectory() as tmp:
                seg = one_run(args.config, args.duration, VARIANTS[name], Path(tmp))
            results[name].append(seg)
            a = np.nanmedian(seg["(a) controller: arrival → torque published"])
            b = np.nanmedian(seg["(b) stamp → torque received by the arm"])
            print(f"run {r} {name}: median (a) {1e6 * a:.0f} µs, (b) {1e6 * b:.0f} µs", flush=True)
    print(f"load average after: {os.getloadavg()}\n")
    summary = {}
    for name in names:
        print(table(name, results[name]) + "\n")
        summary[name] = {
            key: [float(np.nanmedian(r[key])) for r in results[name]] for key in results[name][0]
        }
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
