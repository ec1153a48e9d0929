"""Meshcat replay: a self-contained HTML file, checked in a real headless Chromium."""

from __future__ import annotations

import gzip
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import hmpc_pin

from .conftest import PLANAR3

pytest.importorskip("meshcat", reason="meshcat is not installed (pip install -e '.[viz]')")
from hmpc_pin.apps.viz import export_replay, visual_model

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def short_run():
    robot = hmpc_pin.load_robot(PLANAR3)
    ctrl = hmpc_pin.HierarchicalMPC(robot)
    ref = hmpc_pin.SineReference(3)
    result = hmpc_pin.simulate(robot, ctrl, ref, duration=6.0, q0=np.ones(3))
    return robot, result


def _commands(html: str) -> list[dict]:
    """The Meshcat commands embedded in the page: base64 msgpack data: URIs, and the
    JSON commands of ``hmpcMesh(...)`` whose mesh files are in the shared store."""
    import base64

    import umsgpack

    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    inline = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    return inline + [json.loads(c) for c in re.findall(r"hmpcMesh\((\{.*?\})\);", html)]


def _mesh_store(html: str) -> dict[str, bytes]:
    """The page's shared mesh files, unpacked (gzip, base64)."""
    import base64

    m = re.search(r"const hmpcMeshStore = (\{.*?\});", html)
    if m is None:
        return {}
    return {k: gzip.decompress(base64.b64decode(v)) for k, (_, v) in json.loads(m.group(1)).items()}


def test_replay_is_self_contained_and_holds_the_animation(short_run, tmp_path):
    robot, result = short_run
    path = export_replay(robot, result, tmp_path / "replay.html", fps=25)
    html = path.read_text()
    assert "<html>" in html and "MeshCat.Viewer" in html
    commands = _commands(html)
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    assert any(p.startswith("/meshcat/arm/visuals/link3") for p in objects), objects
    assert any(p.startswith("/meshcat/reference/visuals/") for p in objects)
    assert "/meshcat/tool_path" in objects and "/meshcat/tool_ref" in objects
    (anim,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    link3 = clips["/meshcat/arm/visuals/link3_0"]
    assert link3["fps"] == 25
    # 6 s at 100 Hz decimated to 25 fps: 151 keyframes, the last one at the end of the run
    times = [k["time"] for k in link3["tracks"][0]["keys"]]
    assert times == list(range(151))
    # keyframes carry the arm's motion: link 3's cylinder centre is 0.5 along the link
    # (URDF <visual><origin xyz="0.5 0 0">), at q0 and at the last sample
    positions = {t["name"]: t for t in link3["tracks"]}[".position"]["keys"]
    for key, q in ((positions[0], result.q[0]), (positions[-1], result.q[-1])):
        link = robot.frame_placement(q, "link3")
        centre = link.translation + link.rotation @ np.array([0.5, 0.0, 0.0])
        np.testing.assert_allclose(key["value"], centre, atol=1e-9)
    # no network fetch: no external src/href, no http(s) URL other than XML namespaces
    assert not re.search(r"""(?:src|href)\s*=\s*["']?(?:https?:)?//""", html)
    urls = set(re.findall(r"https?://[^\s\"'<>)`]+", html))
    assert urls <= {"http://www.w3.org/1999/xhtml", "http://www.w3.org/2000/svg"}, urls


def _screenshot(uri: str, png_path, profile):
    cmd = [
        CHROMIUM,
        "--headless=new",
        "--no-sandbox",
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--disable-quic",
        f"--user-data-dir={profile}",
        "--window-size=800,600",
        "--virtual-time-budget=15000",
        f"--screenshot={png_path}",
        uri,
    ]
    subprocess.run(cmd, capture_output=True, timeout=180, check=True)
    from PIL import Image

    return np.asarray(Image.open(png_path).convert("RGB"), dtype=int)


def _differs(a, b) -> float:
    return float(np.mean(np.abs(a - b).max(axis=2) > 40))


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_replay_renders_the_arm_in_a_real_browser(short_run, tmp_path):
    """The arm is visible against an empty scene, and a later frame shows another pose."""
    import meshcat

    robot, result = short_run
    vis = meshcat.Visualizer()
    try:
        vis.delete()
        (tmp_path / "empty.html").write_text(vis.static_html())
    finally:
        vis.window.server_proc.terminate()
    early = export_replay(robot, result, tmp_path / "t0.html", play=False, start_time=0.0)
    late = export_replay(robot, result, tmp_path / "t5.html", play=False, start_time=5.0)
    empty_px = _screenshot(
        (tmp_path / "empty.html").as_uri(), tmp_path / "empty.png", tmp_path / "p0"
    )
    early_px = _screenshot(early.resolve().as_uri(), tmp_path / "t0.png", tmp_path / "p1")
    late_px = _screenshot(late.resolve().as_uri(), tmp_path / "t5.png", tmp_path / "p2")
    # an empty scene and the arm scene differ (arm, ghost, tool path, camera)
    assert _differs(early_px, empty_px) > 0.005
    # between t = 0 (q = 1, 1, 1) and t = 5 s (q ≈ 0) the arm has moved on screen
    assert _differs(early_px, late_px) > 0.002


def test_replay_of_a_mesh_arm_from_example_robot_data(tmp_path):
    """UR5 (meshes via package:// URIs): every visual is loaded and animated."""
    loaders = pytest.importorskip("example_robot_data.robots_loader")
    robot = hmpc_pin.load_robot(loaders.UR5Loader().df_path)
    q0 = np.array([0.0, -1.2, 1.4, -1.0, -1.57, 0.0])
    ctrl = hmpc_pin.make_controller(robot, hmpc_pin.ControllerConfig(compensation="general"))
    ref = hmpc_pin.SineReference(6, amplitude=0.3, offset=q0)
    result = hmpc_pin.simulate(robot, ctrl, ref, duration=1.0, q0=q0)
    html = export_replay(robot, result, tmp_path / "ur5.html", ghost=False).read_text()
    commands = _commands(html)
    meshes = [c for c in commands if c["type"] == "set_object" and "/arm/visuals/" in c["path"]]
    assert len(meshes) == 7  # base, shoulder, upper arm, forearm, 3 wrists
    # the mesh files are in the page (no file or network access when viewed), each the
    # URDF's file byte for byte
    store = _mesh_store(html)
    files = {g.name: Path(g.meshPath).read_bytes() for g in visual_model(robot).geometryObjects}
    for m in meshes:
        name = m["path"].split("/")[-2]
        assert store[m["object"]["object"]["data"]["hmpc_mesh"]] == files[name]
    (anim,) = [c for c in commands if c["type"] == "set_animation"]
    animated = {a["path"] for a in anim["animations"]}
    assert {m["path"].removesuffix("/geom") for m in meshes} == animated


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_live_view_is_served_and_moves_the_arm(tmp_path):
    """A real Meshcat server: the page at LiveView.url shows the arm where it was put."""
    from hmpc_pin.apps.viz import LiveView

    robot = hmpc_pin.load_robot(PLANAR3)
    view = LiveView(robot, ghost=False)
    try:
        assert view.url.startswith("http://127.0.0.1:")
        shots = []
        for k, q in enumerate((np.ones(3), np.array([0.0, -1.0, 0.5]))):
            view(0.0, q, q)
            shots.append(_screenshot(view.url, tmp_path / f"live{k}.png", tmp_path / f"p{k}"))
    finally:
        view.close()
    assert _differs(shots[0], shots[1]) > 0.002


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_live_view_draws_a_target_path(tmp_path):
    """A pose task's target path drawn in the live view changes the picture (real server,
    real browser)."""
    from hmpc_pin.apps.viz import LiveView

    robot = hmpc_pin.load_robot(PLANAR3)
    view = LiveView(robot, ghost=False)
    try:
        view(0.0, np.ones(3), np.ones(3))
        before = _screenshot(view.url, tmp_path / "before.png", tmp_path / "p0")
        theta = np.linspace(0.0, 2 * np.pi, 200)
        view.draw_path(
            "target_path",
            np.column_stack(
                [1.5 + 0.8 * np.cos(theta), np.zeros_like(theta), 1.5 + 0.8 * np.sin(theta)]
            ),
        )
        after = _screenshot(view.url, tmp_path / "after.png", tmp_path / "p1")
    finally:
        view.close()
    changed = np.abs(after - before).max(axis=2) > 40
    # a thin circle of ≈ 50 px radius in an 800 × 600 picture: ≈ 0.1 % of the pixels, green
    assert 0.0004 < changed.mean() < 0.01
    r, g, b = after[changed].mean(axis=0)
    assert g > r and g > 0.9 * b, (r, g, b)


def test_cli_live_view_runs_and_saves(tmp_path, capsys):
    from hmpc_pin.apps.cli import main

    cfg = str(PLANAR3.parent.parent / "configs" / "paper_combined.toml")
    argv = ["run", cfg, "--out", str(tmp_path), "--duration", "1", "--viz", "--speed", "100"]
    assert main(argv) == 0
    assert "Meshcat live view: open http://127.0.0.1:" in capsys.readouterr().out
    assert (tmp_path / "paper_combined.npz").is_file()


def test_missing_meshcat_is_a_clear_message(monkeypatch, tmp_path, capsys):
    """Without meshcat the run still completes and is saved; the view is refused clearly."""
    import sys

    from hmpc_pin.apps.cli import main

    monkeypatch.setitem(sys.modules, "meshcat", None)  # import meshcat -> ImportError
    cfg = str(PLANAR3.parent.parent / "configs" / "paper_combined.toml")
    assert main(["run", cfg, "--out", str(tmp_path), "--duration", "0.5", "--viz"]) == 0
    assert "meshcat is not installed" in capsys.readouterr().err
    assert (tmp_path / "paper_combined.npz").is_file()


def test_busy_port_moves_to_the_next_free_one():
    """A second live view while the first holds its port gets its own server and URL."""
    from hmpc_pin.apps.viz import LiveView

    robot = hmpc_pin.load_robot(PLANAR3)
    first = LiveView(robot)
    try:
        second = LiveView(robot)
        try:
            assert second.url != first.url
        finally:
            second.close()
    finally:
        first.close()


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_panda_replay_stores_each_mesh_once_and_draws_the_same_picture(tmp_path, monkeypatch):
    """A 2 s Panda replay (arm + ghost) is at most 10 MB: every mesh file is stored once,
    compressed, shared by the arm and the ghost. Headless Chromium draws it pixel for
    pixel like the page with every mesh inlined per node (Meshcat's own format)."""
    from hmpc_pin.apps import viz
    from hmpc_pin.experiment.build import Experiment
    from hmpc_pin.experiment.config import load_config

    from .conftest import CONFIGS

    exp = Experiment.from_config(load_config(CONFIGS / "panda_sine.toml"))
    result = exp.run(2.0)
    shared = export_replay(exp.robot, result, tmp_path / "shared.html", play=False,
                           start_time=1.0)  # fmt: skip
    html = shared.read_text()
    assert shared.stat().st_size <= 10e6
    store = _mesh_store(html)
    files = {Path(g.meshPath).read_bytes() for g in visual_model(exp.robot).geometryObjects}
    assert set(store.values()) == files  # each distinct file once
    commands = [c for c in _commands(html) if c["type"] == "set_object"]
    keys = {
        root: sorted(c["object"]["object"]["data"]["hmpc_mesh"] for c in commands
                     if c["path"].startswith(f"/meshcat/{root}/visuals/"))
        for root in ("arm", "reference")
    }  # fmt: skip
    assert keys["arm"] == keys["reference"] and len(keys["arm"]) == len(
        visual_model(exp.robot).geometryObjects
    )
    monkeypatch.setattr(viz, "_share_meshes", lambda page: page)
    inline = export_replay(exp.robot, result, tmp_path / "inline.html", play=False,
                           start_time=1.0)  # fmt: skip
    assert inline.stat().st_size > 2 * shared.stat().st_size
    a = _screenshot(shared.resolve().as_uri(), tmp_path / "a.png", tmp_path / "pa")
    b = _screenshot(inline.resolve().as_uri(), tmp_path / "b.png", tmp_path / "pb")
    assert _differs(a, b) == 0.0
    # and the arm is there: the page differs from an empty scene
    import meshcat

    vis = meshcat.Visualizer()
    try:
        vis.delete()
        (tmp_path / "empty.html").write_text(vis.static_html())
    finally:
        vis.window.server_proc.terminate()
    empty = _screenshot((tmp_path / "empty.html").as_uri(), tmp_path / "e.png", tmp_path / "pe")
    assert _differs(a, empty) > 0.005


# ------------------------------------------------------------------ missing meshes
@pytest.fixture
def mesh_missing_config(tmp_path):
    """The paper's arm with link 1 drawn by a mesh file that does not exist."""
    urdf = PLANAR3.read_text(encoding="utf-8").replace(
        '<geometry><cylinder radius="0.05" length="1.5"/></geometry>',
        '<geometry><mesh filename="meshes/missing_link1.stl"/></geometry>',
        1,
    )
    (tmp_path / "arm.urdf").write_text(urdf, encoding="utf-8")
    cfg = (PLANAR3.parent.parent / "configs" / "paper_combined.toml").read_text(encoding="utf-8")
    cfg = cfg.replace('model = "planar3"', 'urdf = "arm.urdf"')
    path = tmp_path / "cfg.toml"
    path.write_text(cfg, encoding="utf-8")
    return path


def test_missing_mesh_with_replay_is_bad_input_before_the_run(mesh_missing_config, tmp_path,
                                                              capsys):  # fmt: skip
    from hmpc_pin.apps.cli import main

    out = tmp_path / "o"
    argv = ["run", str(mesh_missing_config), "--duration", "0.5", "--out", str(out),
            "--replay", str(out / "r.html")]  # fmt: skip
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: --replay: "), err
    assert "'meshes/missing_link1.stl'" in err and "could not be found" in err
    assert captured.out == "" and not list(out.glob("*"))  # nothing ran, nothing written


def test_missing_mesh_replay_command_is_bad_input(mesh_missing_config, tmp_path, capsys):
    from hmpc_pin.apps.cli import main

    cfg = PLANAR3.parent.parent / "configs" / "paper_combined.toml"
    assert main(["run", str(cfg), "--duration", "0.2", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    argv = [
        "replay",
        str(tmp_path / "paper_combined.npz"),
        "--urdf",
        str(mesh_missing_config.parent / "arm.urdf"),
        "--out",
        str(tmp_path / "r.html"),
    ]
    assert main(argv) == 2  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'meshes/missing_link1.stl'" in err, err
    assert not (tmp_path / "r.html").exists()


def test_missing_mesh_with_live_view_runs_without_it(mesh_missing_config, tmp_path, capsys):
    from hmpc_pin.apps.cli import main

    argv = ["run", str(mesh_missing_config), "--duration", "0.5", "--out", str(tmp_path), "--viz"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "warning: no live view:" in err and "'meshes/missing_link1.stl'" in err
    assert "the run goes on and is saved" in err
    assert hmpc_pin.Result.load(tmp_path / "paper_combined.npz").complete


# ------------------------------------------------------------------ --wait, --keep-open
@pytest.mark.parametrize("flag", ["--wait", "--keep-open"])
def test_live_view_flags_need_viz(tmp_path, capsys, flag):
    from hmpc_pin.apps.cli import main

    cfg = str(PLANAR3.parent.parent / "configs" / "paper_combined.toml")
    assert main(["run", cfg, "--out", str(tmp_path), "--duration", "0.2", flag]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {flag}: applies to the live view only; add --viz"), err
    assert not list(tmp_path.glob("*.npz"))


@pytest.mark.parametrize("speed", ["0", "-1", "nan"])
def test_a_live_view_speed_must_be_positive(tmp_path, capsys, speed):
    """``--speed`` (the live view's playback rate) outside (0, inf]: exit 2 with one line
    naming it, before anything runs or is written."""
    from hmpc_pin.apps.cli import main

    cfg = str(PLANAR3.parent.parent / "configs" / "paper_combined.toml")
    argv = ["run", cfg, "--out", str(tmp_path / "out"), "--duration", "0.2", "--viz"]
    assert main([*argv, "--speed", speed]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --speed: expected a number > 0")
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed (apt-get install chromium)")
def test_live_view_waits_for_a_browser_and_stays_open(tmp_path):
    """``run --viz --wait --keep-open`` in a real subprocess: nothing runs until headless
    Chromium opens the page; after the run the files are written and the page is still
    served; Ctrl-C then closes it with exit 0 and stops the Meshcat server."""
    import os
    import signal
    import sys
    import time
    import urllib.request

    cfg = str(PLANAR3.parent.parent / "configs" / "paper_combined.toml")
    out = tmp_path / "o"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hmpc_pin", "run", cfg, "--duration", "1", "--out", str(out),
         "--viz", "--wait", "--keep-open", "--speed", "10"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    import threading

    watchdog = threading.Timer(180, lambda: os.killpg(proc.pid, signal.SIGKILL))
    watchdog.start()  # a blocking readline cannot hang the suite
    try:
        assert proc.stdout.readline().startswith("Meshcat live view: open http://127.0.0.1:")
        line = proc.stdout.readline()
        assert line.startswith("waiting for a browser at "), line
        url = re.search(r"http://\S+", line).group(0)
        time.sleep(3.0)
        assert proc.poll() is None and not out.joinpath("paper_combined.npz").exists()
        _screenshot(url, tmp_path / "live.png", tmp_path / "profile")
        lines = []
        while not (line := proc.stdout.readline()).startswith("live view kept open"):
            assert line, f"the command ended: {proc.wait()} {proc.stderr.read()}"
            lines.append(line)
        assert f"wrote {out / 'paper_combined.npz'}\n" in lines
        assert hmpc_pin.Result.load(out / "paper_combined.npz").complete
        with urllib.request.urlopen(url, timeout=10) as page:
            assert page.status == 200
        from .test_interrupts import _alive, _descendants

        server = _descendants(proc.pid)  # the Meshcat server (its own session)
        assert server
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    deadline = time.monotonic() + 5.0
    while any(_alive(p) for p in server) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(p) for p in server)  # the server stopped with the command


def test_replay_of_a_pose_task_draws_the_target_path_beside_the_tool_path(tmp_path):
    """Pose task: the lines are the frame's measured and target positions (the result's
    ee_pos and ee_pos_ref), not the forward kinematics of the last frame."""
    from dataclasses import replace

    from .conftest import CONFIGS

    config = hmpc_pin.load_config(CONFIGS / "ur5_circle.toml")
    config = replace(config, simulation=replace(config.simulation, duration=0.5))
    experiment = hmpc_pin.Experiment.from_config(config)
    result = experiment.run()
    html = export_replay(experiment.robot, result, tmp_path / "c.html", ghost=False).read_text()
    lines = {
        c["path"]: c["object"]
        for c in _commands(html)
        if c["type"] == "set_object" and c["path"] in ("/meshcat/tool_path", "/meshcat/target_path")
    }
    assert set(lines) == {"/meshcat/tool_path", "/meshcat/target_path"}
    target = lines["/meshcat/target_path"]["geometries"][0]["data"]["attributes"]["position"]
    pts = np.frombuffer(target["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(pts, result.ee_pos_ref, atol=1e-6)
