"""Meshcat replay: a self-contained HTML file, checked in a real headless Chromium."""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

import hmpc_pin

from .conftest import PLANAR3

pytest.importorskip("meshcat", reason="meshcat is not installed (pip install -e '.[viz]')")
from hmpc_pin.apps.viz import export_replay

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def short_run():
    robot = hmpc_pin.load_robot(PLANAR3)
    ctrl = hmpc_pin.HierarchicalMPC(robot)
    ref = hmpc_pin.SineReference(3)
    result = hmpc_pin.simulate(robot, ctrl, ref, duration=6.0, q0=np.ones(3))
    return robot, result


def _commands(html: str) -> list[dict]:
    """The Meshcat commands embedded in the page (base64 msgpack data: URIs)."""
    import base64

    import umsgpack

    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


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
    ctrl = hmpc_pin.HierarchicalMPC(
        robot, hmpc_pin.ControllerConfig(observer=hmpc_pin.ObserverConfig(kind="general"))
    )
    ref = hmpc_pin.SineReference(6, amplitude=0.3, offset=q0)
    result = hmpc_pin.simulate(robot, ctrl, ref, duration=1.0, q0=q0)
    html = export_replay(robot, result, tmp_path / "ur5.html", ghost=False).read_text()
    commands = _commands(html)
    meshes = [c for c in commands if c["type"] == "set_object" and "/arm/visuals/" in c["path"]]
    assert len(meshes) == 7  # base, shoulder, upper arm, forearm, 3 wrists
    # the mesh files are inlined in the page (no file or network access when viewed)
    assert all(len(m["object"]["object"].get("data", "")) > 1000 for m in meshes)
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
