"""Meshcat views of a run: a self-contained HTML replay, and a live view.

The arm is drawn from the URDF's visual geometry through Pinocchio's
``MeshcatVisualizer``; the reference is drawn as a translucent ghost arm and the
tool path as a line.

Scale gotcha (SPEC §5): Meshcat animation frames keep only position and
rotation, while Pinocchio bakes a mesh's scale into the transform it sends.
Each geometry is therefore loaded one node deeper (``.../<name>/geom``) with its
scale as a static transform, and only the parent node ``.../<name>`` is
animated with the unscaled placement ``oMg``.

Requires the ``viz`` extra (``pip install "hmpc_pin[viz]"``).
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..exceptions import VizError, install_command

__all__ = ["LiveView", "VizError", "export_replay", "visual_model"]

ARM = "arm"
GHOST = "reference"
GHOST_RGBA = [0.6, 0.6, 0.6, 0.35]
OBSTACLE = "obstacle"


def draw_obstacle(vis, obstacle: dict | None) -> None:
    """Draw the MuJoCo scene's box (``{"position": [x, y, z], "size": [half-lengths]}``
    [m], as recorded in a result's ``meta["obstacle"]``); nothing for ``None``."""
    if not obstacle:
        return
    geom = _meshcat().geometry
    size = [2.0 * float(h) for h in obstacle["size"]]
    material = geom.MeshLambertMaterial(color=0x8C8C8C, opacity=0.6, transparent=True)
    vis[OBSTACLE].set_object(geom.Box(size), material)
    placement = np.eye(4)
    placement[:3, 3] = np.asarray(obstacle["position"], dtype=float)
    vis[OBSTACLE].set_transform(placement)


#: The message when Meshcat is missing: the extra that installs it (as a wheel user types it).
MESHCAT_MISSING = (
    f"meshcat is not installed; install the viz extra (hmpc_pin[viz]): {install_command('viz')}"
)


def require_meshcat() -> None:
    """Raise :class:`~hmpc_pin.exceptions.VizError` (:data:`MESHCAT_MISSING`) now when
    Meshcat cannot be imported, e.g. before a run that ends with a replay (its
    dependencies' deprecation notices, not the user's business, are not shown)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        _meshcat()


def _meshcat():
    try:
        import meshcat
        import meshcat.animation
        import meshcat.geometry
    except ImportError as exc:
        raise VizError(MESHCAT_MISSING) from exc
    return meshcat


def visual_model(robot) -> pin.GeometryModel:
    """The visual geometry of ``robot``'s URDF.

    ``package://`` mesh URIs are resolved against every ancestor directory of the
    URDF (e.g. ``share/`` for example-robot-data's ``package://example-robot-data/...``).
    """
    source = Path(robot.source).resolve()
    dirs = [str(p) for p in source.parents]
    try:
        return pin.buildGeomFromUrdf(
            robot.model, str(source), pin.GeometryType.VISUAL, package_dirs=dirs
        )
    except ValueError as exc:  # Pinocchio: "Mesh <file> could not be found."
        m = re.search(r"Mesh (.*) could not be found", str(exc))
        mesh = m.group(1) if m else str(exc)
        raise VizError(
            f"the URDF {str(source)!r} names the mesh {mesh!r}, which could not be found "
            f"(relative to the URDF's folder, package:// against its parent folders); "
            "install the meshes next to the URDF or draw without a view (the run itself "
            "needs no mesh)"
        ) from exc


def _visualizer_class():
    from pinocchio.visualize import MeshcatVisualizer

    class _NestedVisualizer(MeshcatVisualizer):
        """Loads each geometry at ``<group>/<name>/geom`` so its parent can be animated."""

        def getViewerNodeName(self, geometry_object, geometry_type):
            return super().getViewerNodeName(geometry_object, geometry_type) + "/geom"

    return _NestedVisualizer


def _load_scene(vis, robot, gmodel, ghost: bool) -> list[str]:
    """Load the arm (and the ghost reference arm) into ``vis``; return the root names.

    Each geometry sits at ``<root>/visuals/<name>/geom`` with its mesh scale as a static
    transform, so that ``<root>/visuals/<name>`` can carry the unscaled placement.
    """
    # No collision model: it would be loaded (hidden) as a second copy of every mesh.
    viz = _visualizer_class()(robot.model, None, gmodel)
    with contextlib.redirect_stdout(io.StringIO()):
        viz.initViewer(viewer=vis, loadModel=False)
    roots = [ARM, GHOST] if ghost else [ARM]
    for root in roots:
        viz.loadViewerModel(rootNodeName=root, visual_color=None if root == ARM else GHOST_RGBA)
        for g in gmodel.geometryObjects:
            scale = np.diag([*np.asarray(g.meshScale, float), 1.0])
            vis[f"{root}/visuals/{g.name}/geom"].set_transform(scale)
    _front_camera(vis, robot)
    return roots


def _place(node, root, robot, data, gmodel, gdata, q) -> None:
    """Set the unscaled placement of every geometry of arm ``root`` at ``q`` on ``node``."""
    pin.updateGeometryPlacements(robot.model, data, gmodel, gdata, q)
    for i, g in enumerate(gmodel.geometryObjects):
        node[f"{root}/visuals/{g.name}"].set_transform(gdata.oMg[i].homogeneous)


def _start_server(meshcat):
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            return meshcat.Visualizer()
    except Exception as exc:  # zmq/tornado failures surface as assorted types
        raise VizError(f"cannot start a Meshcat server: {exc}") from exc


def _stop_server(vis) -> None:
    proc = getattr(vis.window, "server_proc", None)
    if proc is not None:
        proc.terminate()
        proc.wait(timeout=10)


def _reach(robot) -> float:
    """Sum of the joint offsets and the tool offset [m]: a bound on the arm's extent."""
    model = robot.model
    tool = model.frames[model.getFrameId(robot.tool_frame)].placement.translation
    return float(
        sum(np.linalg.norm(model.jointPlacements[j].translation) for j in range(1, model.njoints))
        + np.linalg.norm(tool)
    )


def _front_camera(vis, robot) -> None:
    """Look at the arm's x–z plane from −y, far enough to see the whole reach.

    Meshcat's camera lives in a y-up frame: local (x, y, z) is world (x, −z, y).
    """
    reach = max(_reach(robot), 0.2)
    center = np.eye(4)
    center[:3, 3] = [0.3 * reach, 0.0, 0.0]
    vis["/Cameras/default"].set_transform(center)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [0.0, 0.0, 1.7 * reach])


class LiveView:
    """Animate a running simulation in a Meshcat server on localhost.

    Pass it as ``simulate(..., on_step=view)``: every control instant it moves
    the arm (and the translucent reference arm) at most ``fps`` times per second,
    and sleeps so that simulated time runs at ``speed`` × real time.

    Args:
        robot: The arm.
        speed: Simulated seconds per real second (1 = real time; ``inf`` = as fast as possible).
        fps: Maximum display rate [1/s].
        ghost: Draw the reference as a translucent arm.
        obstacle: The MuJoCo scene's box to draw (:func:`draw_obstacle`), or ``None``.

    Attributes:
        url: The browser URL of the Meshcat server.
    """

    def __init__(
        self,
        robot,
        speed: float = 1.0,
        fps: float = 50.0,
        ghost: bool = True,
        obstacle: dict | None = None,
    ):
        import time

        meshcat = _meshcat()
        if not speed > 0:
            raise VizError(f"speed={speed!r}; expected a number > 0")
        self._time = time
        self.robot, self.speed, self.period = robot, float(speed), 1.0 / fps
        self.gmodel = visual_model(robot)
        self.gdata = self.gmodel.createData()
        self.data = robot.model.createData()
        self.vis = _start_server(meshcat)
        self.url = self.vis.url()
        self.vis.delete()
        self.roots = _load_scene(self.vis, robot, self.gmodel, ghost)
        draw_obstacle(self.vis, obstacle)
        self._interval = self.period * self.speed if np.isfinite(self.speed) else self.period
        self._start = None
        self._last = -np.inf

    def show(self, root: str, q) -> None:
        """Place the arm ``root`` (``"arm"`` or ``"reference"``) at ``q``."""
        _place(self.vis, root, self.robot, self.data, self.gmodel, self.gdata, q)

    def __call__(self, t: float, q, q_ref) -> None:
        now = self._time.perf_counter()
        if self._start is None:
            self._start = now - t / self.speed
        if t - self._last < self._interval and t > 0:
            return
        self._last = t
        self.show(ARM, q)
        if GHOST in self.roots:
            self.show(GHOST, q_ref)
        delay = self._start + t / self.speed - self._time.perf_counter()
        if delay > 0 and np.isfinite(delay):
            self._time.sleep(delay)

    def wait_for_browser(self, poll: float = 0.1) -> None:
        """Block until a browser has opened :attr:`url` (Ctrl-C stops waiting).

        Polls the server's answer every ``poll`` seconds [s], so a ``KeyboardInterrupt``
        is raised at once.
        """
        # The server logs "opened: <handler>" on its stderr (a pipe to this process) when a
        # page connects. (Meshcat's own ``Visualizer.wait`` leaves the command socket stuck:
        # the next command never gets its reply.)
        import os
        import select

        proc = getattr(self.vis.window, "server_proc", None)
        if proc is None or proc.stderr is None:
            raise VizError("this view does not own its Meshcat server; cannot wait for a browser")
        fd, seen = proc.stderr.fileno(), b""
        while b"opened:" not in seen:
            if select.select([fd], [], [], poll)[0]:
                chunk = os.read(fd, 65536)
                if not chunk:
                    raise VizError("the Meshcat server stopped while waiting for a browser")
                seen = seen[-64:] + chunk

    def hold(self) -> None:
        """Keep serving the view, the arm at its last pose, until Ctrl-C (which ends the
        hold normally: returns instead of raising)."""
        try:
            while True:
                self._time.sleep(0.2)
        except KeyboardInterrupt:
            return

    def draw_path(self, name: str, points, color: int = 0x2CA02C) -> None:
        """Draw the polyline ``points`` (m, 3) [m] as the node ``name`` (e.g. a pose
        task's target path, green)."""
        geom = _meshcat().geometry
        pts = np.asarray(points, dtype=np.float32).T
        self.vis[name].set_object(
            geom.Line(geom.PointsGeometry(pts), geom.LineBasicMaterial(color=color))
        )

    def close(self) -> None:
        """Stop the Meshcat server."""
        _stop_server(self.vis)


def _frames(t: np.ndarray, fps: float) -> np.ndarray:
    """Indices of samples kept so that frames are at most ``fps`` per second."""
    if len(t) < 2:
        return np.arange(len(t))
    step = max(1, int(np.ceil((1.0 / fps) / (t[1] - t[0]) - 1e-9)))
    idx = np.arange(0, len(t), step)
    if idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    return idx


def _tool_points(robot, qs) -> np.ndarray:
    model, data = robot.model, robot.model.createData()
    fid = model.getFrameId(robot.tool_frame)
    pts = []
    for q in qs:
        pin.framesForwardKinematics(model, data, q)
        pts.append(data.oMf[fid].translation.copy())
    return np.array(pts)


def export_replay(
    robot,
    result,
    path: str | Path,
    *,
    fps: float = 50.0,
    ghost: bool = True,
    tool_path: bool = True,
    play: bool = True,
    start_time: float = 0.0,
) -> Path:
    """Write one self-contained HTML file that replays ``result`` as a Meshcat animation.

    The page needs no server and no network: Meshcat's ``static_html`` inlines the
    viewer's JavaScript and the scene, animation included (play/pause/scrub in
    the page's Animations panel). A run on MuJoCo with an obstacle draws it too
    (``result.meta["obstacle"]``).

    Args:
        robot: The arm (its URDF's visual geometry is drawn).
        result: A :class:`~hmpc_pin.sim.result.Result`.
        path: Output ``.html`` file.
        fps: Maximum animation frame rate [1/s]; samples are decimated to it.
        ghost: Draw the reference as a translucent arm.
        tool_path: Draw the tool's path (and the reference tool path) as lines; for a pose
            task (``result.ee_pos`` set) the task frame's path (red) beside its target path
            (green, ``result.ee_pos_ref``).
        play: Start playing the animation when the page opens.
        start_time: Time [s] of the pose shown before (or without) playing.

    Returns:
        The path written.
    """
    meshcat = _meshcat()
    geom = meshcat.geometry
    gmodel = visual_model(robot)
    gdata = gmodel.createData()
    data = robot.model.createData()
    vis = _start_server(meshcat)
    try:
        vis.delete()
        names = _load_scene(vis, robot, gmodel, ghost)
        draw_obstacle(vis, result.meta.get("obstacle"))
        roots = [(name, result.q if name == ARM else result.q_ref) for name in names]
        if tool_path:
            lines = [
                ("tool_path", _tool_points(robot, result.q), 0xD62728),
                ("tool_ref", _tool_points(robot, result.q_ref), 0x333333),
            ]
            if getattr(result, "ee_pos", None) is not None:  # pose task: its frame's paths
                lines = [
                    ("tool_path", result.ee_pos, 0xD62728),
                    ("target_path", result.ee_pos_ref, 0x2CA02C),
                ]
            for name, pts, color in lines:
                vis[name].set_object(
                    geom.Line(
                        geom.PointsGeometry(np.asarray(pts).T.astype(np.float32)),
                        geom.LineBasicMaterial(color=color),
                    )
                )

        idx = _frames(result.t, fps)
        anim = meshcat.animation.Animation(default_framerate=fps)
        for frame_no, k in enumerate(idx):
            with anim.at_frame(vis, frame_no) as frame:
                for root, qs in roots:
                    _place(frame, root, robot, data, gmodel, gdata, qs[k])
        # the static scene shows the pose at start_time
        k0 = int(np.argmin(np.abs(result.t - start_time)))
        for root, qs in roots:
            _place(vis, root, robot, data, gmodel, gdata, qs[k0])
        vis.set_animation(anim, play=play, repetitions=1)
        html = _share_meshes(vis.static_html())
    finally:
        _stop_server(vis)
    path = Path(path)
    path.write_text(html, encoding="utf-8")
    return path


_COMMAND = re.compile(
    r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)\s*'
    r"\.then\(res => res\.arrayBuffer\(\)\)\s*"
    r"\.then\(buffer => viewer\.handle_command_bytearray\(new Uint8Array\(buffer\)\)\);"
)
_VIEWER = 'var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));'
_MESH_MIN = 1024  # [bytes] mesh files shorter than this stay inline

# Unpacks the shared meshes (gzip, base64) in the page and hands each command to the viewer.
_MESH_JS = """
const hmpcMeshStore = %s;
const hmpcMeshCache = {};
function hmpcUnpack(key) {
  if (!(key in hmpcMeshCache)) {
    const [kind, b64] = hmpcMeshStore[key];
    const bin = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
    const gunzip = new DecompressionStream("gzip");
    const body = new Response(new Blob([bin]).stream().pipeThrough(gunzip));
    hmpcMeshCache[key] = kind === "text" ? body.text()
      : body.arrayBuffer().then((b) => new Uint8Array(b));
  }
  return hmpcMeshCache[key];
}
async function hmpcFill(x) {
  if (Array.isArray(x)) {
    for (let i = 0; i < x.length; i++) x[i] = await hmpcFill(x[i]);
  } else if (x !== null && typeof x === "object") {
    if (Object.keys(x).length === 1 && "hmpc_mesh" in x) return await hmpcUnpack(x.hmpc_mesh);
    for (const k of Object.keys(x)) x[k] = await hmpcFill(x[k]);
  }
  return x;
}
function hmpcMesh(cmd) { hmpcFill(cmd).then((c) => viewer.handle_command(c)); }
"""


def _share_meshes(html: str) -> str:
    """Store every mesh file of a Meshcat static page once, compressed, shared by all the
    nodes that draw it (the arm and its ghost).

    Meshcat inlines a mesh file in each ``set_object`` command (as base64 msgpack), so a
    mesh drawn twice is stored twice. Here each such command becomes JSON whose mesh data
    is a key into one table of gzip-compressed files; the page unpacks each file once
    (``DecompressionStream``) and hands the command to the viewer unchanged otherwise.
    """
    import base64
    import gzip
    import hashlib
    import json

    import umsgpack

    store: dict[str, list[str]] = {}

    def pull(x):
        if isinstance(x, dict):
            data = x.get("data")
            if "format" in x and isinstance(data, (str, bytes)) and len(data) >= _MESH_MIN:
                raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
                key = hashlib.sha256(raw).hexdigest()[:16]
                if key not in store:
                    packed = gzip.compress(raw, compresslevel=9, mtime=0)
                    kind = "text" if isinstance(data, str) else "bytes"
                    store[key] = [kind, base64.b64encode(packed).decode("ascii")]
                x = {**x, "data": {"hmpc_mesh": key}}
            return {k: pull(v) for k, v in x.items()}
        if isinstance(x, list):
            return [pull(v) for v in x]
        return x

    def replace(match: re.Match) -> str:
        command = umsgpack.unpackb(base64.b64decode(match.group(1)))
        if command.get("type") != "set_object":
            return match.group(0)
        shared = pull(command)
        if shared == command:
            return match.group(0)
        try:
            text = json.dumps(shared, separators=(",", ":"), allow_nan=False)
        except (TypeError, ValueError):  # not JSON (typed arrays): leave it inline
            return match.group(0)
        return f"hmpcMesh({text});"

    html = _COMMAND.sub(replace, html)
    if not store:
        return html
    table = json.dumps(store, separators=(",", ":"), sort_keys=True)
    return html.replace(_VIEWER, _VIEWER + (_MESH_JS % table), 1)
