"""The workspace (:mod:`hmpc_pin.model.workspace`, ``[workspace]``): ``init``'s sine keeps
every moving link above the mounting plane and clear of the other links, and ``check``
flags a reference that does not, naming the link and the time.

The oracle is independent of the package's geometry code: yourdfpy's forward kinematics
and its trimesh meshes of the URDF's ``<collision>`` elements (the lowest vertex of each
link in the world), and coal's collision test called directly on those meshes, with the
pairs to test read from the URDF's tree and the SRDF's XML here."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from functools import partial
from pathlib import Path

import coal
import numpy as np
import pytest
import yourdfpy

from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError, URDFError, ValidityWarning
from hmpc_pin.experiment.config import WorkspaceConfig, load_config
from hmpc_pin.experiment.init import init_config, plan
from hmpc_pin.model.catalogue import example_robot_srdf, example_robot_urdf

#: Arms whose init reference is checked (no SRDF: ur10; SRDF postures: panda, xarm7, z1).
ARMS = ("ur5", "ur10", "panda", "xarm7", "z1")
#: The UR arms' joints, in order.
UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint")  # fmt: skip
#: Samples of one period of the sine.
SAMPLES = 400


class Oracle:
    """yourdfpy + trimesh + coal on an arm's URDF, nothing of hmpc_pin's geometry."""

    def __init__(self, name: str, locked=(), allowed=()):
        path = example_robot_urdf(name)
        self.urdf = yourdfpy.URDF.load(
            str(path),
            build_scene_graph=True,
            build_collision_scene_graph=True,
            load_meshes=False,
            load_collision_meshes=True,
            filename_handler=partial(yourdfpy.filename_handler_magic, dir=str(path.parent)),
        )
        scene = self.urdf.collision_scene
        self.nodes = []  # (link, node, vertices, coal mesh)
        for node in scene.graph.nodes_geometry:
            _, geom = scene.graph[node]
            mesh = scene.geometry[geom]
            link = self._link_of(node)
            bvh = coal.BVHModelOBBRSS()
            bvh.beginModel(len(mesh.faces), len(mesh.vertices))
            bvh.addVertices(np.ascontiguousarray(mesh.vertices, dtype=float))
            bvh.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
            bvh.endModel()
            self.nodes.append((link, node, np.asarray(mesh.vertices, float), bvh))
        srdf, _ = example_robot_srdf(name)
        self.disabled = set()
        if srdf is not None:
            for d in ET.parse(srdf).getroot().iter("disable_collisions"):
                self.disabled.add(frozenset((d.get("link1"), d.get("link2"))))
        self.disabled |= {frozenset(p) for p in allowed}
        # the rigid body of each link: the nearest link up the tree (itself included)
        # whose parent joint moves (not fixed, not locked); adjacent bodies meet at their
        # joint
        parent = {j.child: (j.parent, j.type, j.name) for j in self.urdf.robot.joints}
        self.body = {}
        for link in self.urdf.link_map:
            body = link
            while body in parent and (parent[body][1] == "fixed" or parent[body][2] in locked):
                body = parent[body][0]
            self.body[link] = body
        self.parent_body = {
            b: self.body[parent[b][0]] if b in parent else None for b in set(self.body.values())
        }
        self.base = self.body[self.urdf.base_link]

    def _link_of(self, node: str) -> str:
        graph = self.urdf.collision_scene.graph
        parent = graph.transforms.parents[node]
        return parent if parent in self.urdf.link_map else self._link_of(parent)

    def pose(self, cfg: dict[str, float]) -> None:
        self.urdf.update_cfg(
            {k: np.float64(v) for k, v in cfg.items() if k in self.urdf.actuated_joint_names}
        )

    def lowest(self) -> dict[str, float]:
        """Per link, the lowest z [m] of its collision meshes' vertices in the world."""
        out: dict[str, float] = {}
        scene = self.urdf.collision_scene
        for link, node, vertices, _ in self.nodes:
            T, _ = scene.graph.get(node)
            z = float((vertices @ T[:3, :3].T + T[:3, 3])[:, 2].min())
            out[link] = min(out.get(link, math.inf), z)
        return out

    def checked_pair(self, a: str, b: str) -> bool:
        ba, bb = self.body[a], self.body[b]
        if ba == bb or frozenset((a, b)) in self.disabled:
            return False
        return self.parent_body[ba] != bb and self.parent_body[bb] != ba

    def collisions(self) -> set[tuple[str, str]]:
        scene = self.urdf.collision_scene
        placed = []
        for link, node, _, bvh in self.nodes:
            T, _ = scene.graph.get(node)
            placed.append((link, bvh, coal.Transform3s(T[:3, :3], T[:3, 3])))
        out = set()
        for i, (la, ga, Ta) in enumerate(placed):
            for lb, gb, Tb in placed[i + 1 :]:
                if not self.checked_pair(la, lb):
                    continue
                request, result = coal.CollisionRequest(), coal.CollisionResult()
                if coal.collide(ga, Ta, gb, Tb, request, result):
                    out.add((la, lb))
        return out


def _sine(p, samples: int = SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """One period of init's sine, r = o + a sin(2π f t): times [s] and postures."""
    t = np.linspace(0.0, 1.0 / p.frequency, samples)
    return t, p.offset + np.outer(np.sin(2 * np.pi * p.frequency * t), p.amplitude)


@pytest.mark.parametrize("name", ARMS)
def test_init_reference_keeps_every_link_above_the_plane_and_clear(name):
    """Sampled densely over a period, the sine init chose keeps every link's collision
    mesh above the plane z = 0, the links that move down or up by `margin` (0.02 m, less
    1 mm for the sampling), and no pair the SRDF or adjacency does not exempt collides
    (coal on yourdfpy's meshes and kinematics)."""
    p = plan(name)
    oracle = Oracle(name, p.locked, p.workspace_settings.allowed_pairs)
    _, Q = _sine(p)
    lows: dict[str, list[float]] = {}
    hits = set()
    for k, q in enumerate(Q):
        oracle.pose({**dict(zip(p.robot.joint_names, q, strict=True)), **p.locked})
        for link, z in oracle.lowest().items():
            lows.setdefault(link, []).append(z)
        if k % 4 == 0:
            hits |= oracle.collisions()
    moving = [link for link in lows if oracle.body[link] != oracle.base]
    assert moving
    for link in moving:
        z = np.array(lows[link])
        assert z.min() >= 0.0, (name, link, z.min())
        if np.ptp(z) > 1e-6:  # a link the motion moves up or down
            assert z.min() >= WorkspaceConfig().margin - 1e-3, (name, link, z.min())
    assert not hits, (name, hits)


def _ur5_config(tmp_path, reference: str, workspace: bool = True) -> str:
    path = tmp_path / "ur5_through_table.toml"
    path.write_text(
        '[robot]\nmodel = "ur5"\ngravity = 9.81\n[controller]\ncompensation = "general"\n'
        f"[reference]\n{reference}\n[simulation]\nduration = 5.0\n"
        + ("[workspace]\nheight = 0.0\nmargin = 0.02\n" if workspace else ""),
        encoding="utf-8",
    )
    return str(path)


def test_check_names_the_link_and_time_a_reference_goes_through_the_table(tmp_path, capsys):
    """UR5 stretched out, its shoulder lifted by 0.5 sin(0.2π t): the arm swings down
    into the table. ``check`` exits 1 naming the link that first leaves the workspace and
    the time, within one scan step of the first time the oracle finds any link's mesh
    within the margin of the plane."""
    path = _ur5_config(
        tmp_path,
        "amplitude = [0, 0.5, 0, 0, 0, 0]\nfrequency = 0.1\noffset = [0, -0.1, 0, 0, 0, 0]",
    )
    assert main(["check", path, "--no-engine"]) == 1
    out = capsys.readouterr().out
    problems = [line for line in out.splitlines() if line.startswith("problem: link")]
    assert problems, out
    oracle = Oracle("ur5")
    t = np.arange(0.0, 5.0 + 1e-9, 0.005)
    first = None
    for tk in t:
        q = [0.0, -0.1 + 0.5 * math.sin(0.2 * math.pi * tk), 0.0, 0.0, 0.0, 0.0]
        oracle.pose(dict(zip(UR_JOINTS, q, strict=True)))
        low = {link: z for link, z in oracle.lowest().items() if oracle.body[link] != oracle.base}
        # (the shoulder turns about the vertical only: its height is where it is mounted)
        below = [link for link, z in low.items() if z < 0.02 and link != "shoulder_link"]
        if below:
            first = (float(tk), below)
            break
    assert first is not None
    line = problems[0]
    named = line.split("'")[1]
    time = float(line.split("at t = ")[1].split(" s")[0])
    assert named in first[1], (line, first)
    assert abs(time - first[0]) <= 0.011, (line, first)
    # without a [workspace] table: the same finding, as a warning against the default plane
    path = _ur5_config(
        tmp_path,
        "amplitude = [0, 0.5, 0, 0, 0, 0]\nfrequency = 0.1\noffset = [0, -0.1, 0, 0, 0, 0]",
        workspace=False,
    )
    assert main(["check", path, "--no-engine"]) == 0
    err = capsys.readouterr().err  # warnings on stderr, as run's
    assert f"warning: link {named!r} leaves the workspace at t = " in err


def test_check_names_two_links_that_collide_and_when(tmp_path, capsys):
    """UR5 folding its elbow to 2.7 + 0.4 sin(0.2π t) rad: the wrist meets the upper arm
    and the shoulder. ``check`` names a pair the oracle (coal on yourdfpy's meshes) finds
    colliding, first at a time within one scan step of the oracle's."""
    path = _ur5_config(
        tmp_path,
        "amplitude = [0, 0, 0.4, 0, 0, 0]\nfrequency = 0.1\n"
        "offset = [0, -1.5708, 2.7, -1.5708, 0, 0]",
    )
    assert main(["check", path, "--no-engine"]) == 1
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if "collide" in line and "problem:" in line]
    assert lines, out
    oracle = Oracle("ur5")
    first: dict[frozenset, float] = {}
    for tk in np.arange(0.0, 5.0 + 1e-9, 0.01):
        q = [0.0, -1.5708, 2.7 + 0.4 * math.sin(0.2 * math.pi * tk), -1.5708, 0.0, 0.0]
        oracle.pose(dict(zip(UR_JOINTS, q, strict=True)))
        for pair in oracle.collisions():
            first.setdefault(frozenset(pair), float(tk))
    assert first
    for line in lines:
        a, b = line.split("'")[1], line.split("'")[3]
        time = float(line.split("from t = ")[1].split(" s")[0])
        assert frozenset((a, b)) in first, (line, first)
        assert abs(time - first[frozenset((a, b))]) <= 0.011, (line, first)


def test_init_refuses_an_arm_with_no_posture_inside_the_workspace(write_urdf, tmp_path, capsys):
    """A link 0.5 m long on a joint 0.1 m above the plane whose limits keep it pointing
    down (2 to 4.3 rad from the upright, about a horizontal axis), a second link at its
    end: no posture keeps the arm above the table. init exits 2 with one line that names
    the link; with the table 0.9 m lower the arm swings freely."""
    box = (
        '<link name="{n}"><inertial><origin xyz="0 0 {c}"/><mass value="1"/>'
        '<inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>'
        '<collision><origin xyz="0 0 {c}"/><geometry><box size="0.04 0.04 {h}"/></geometry>'
        "</collision></link>"
    )

    def hinge(name, parent, child, z, lower, upper):
        return (
            f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="0 0 {z}"/><axis xyz="0 1 0"/>'
            f'<limit lower="{lower}" upper="{upper}" effort="50" velocity="3"/></joint>'
        )

    text = (
        '<?xml version="1.0"?>\n<robot name="hanging">\n'
        + box.format(n="base", c=0.05, h=0.1)
        + box.format(n="arm", c=0.25, h=0.5)
        + box.format(n="hand", c=0.1, h=0.2)
        + hinge("j1", "base", "arm", 0.1, 2.0, 4.3)
        + hinge("j2", "arm", "hand", 0.5, -1.0, 1.0)
        + "\n</robot>\n"
    )
    urdf = write_urdf(text)
    table = WorkspaceConfig(height=0.0)
    with pytest.raises(URDFError, match="no posture found"):
        init_config(urdf, workspace=table)
    out = str(tmp_path / "x.toml")
    assert main(["init", str(urdf), "--out", out, "--plane-height", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'arm'" in err[0] and "--plane-height" in err[0]
    assert not (tmp_path / "x.toml").exists()
    assert main(["init", str(urdf), "--out", out, "--plane-height", "-0.9", "--duration", "1"]) == 0
    assert load_config(out).workspace.height == -0.9
    # no plane given: no posture keeps the arm above its root, which therefore is no
    # table; the plane is put under the whole sine (said in a warning)
    with pytest.warns(ValidityWarning, match="does not stand on a table"):
        p = plan(urdf)
    height = p.workspace_settings.height
    assert height < -0.4
    _, Q = _sine(p)
    low = p.workspace.clearance(Q)[:, p.workspace.checked].min() + height  # z of the lowest
    assert height <= low - 0.02 < height + 0.001


def test_init_writes_the_workspace_table_and_check_passes_it(tmp_path, capsys):
    """init ur10 (no SRDF: the middle of the limits is the arm stretched over the table)
    writes a [workspace] table and a posture that check finds inside it."""
    path = tmp_path / "ur10.toml"
    assert main(["init", "ur10", "--out", str(path), "--duration", "2"]) == 0
    config = load_config(path)
    assert config.workspace is not None and config.workspace.margin == 0.02
    assert "moved until the whole sine keeps every link above the mounting plane" in (
        path.read_text()
    )
    capsys.readouterr()
    assert main(["check", str(path), "--no-engine"]) == 0
    out = capsys.readouterr().out
    assert "workspace: plane height 0 m" in out and "no two links collide" in out


@pytest.mark.parametrize(
    ("table", "key", "expected"),
    [
        ("normal = [0, 0]", "workspace.normal", "expected 3 numbers"),
        ("normal = [0, 0, 0]", "workspace.normal", "not all 0"),
        ("margin = -0.1", "workspace.margin", ">= 0"),
        ("height = 'low'", "workspace.height", "expected a number"),
        ("plane = 1", "workspace.plane", "unknown key"),
        ("allowed_pairs = [['a']]", "workspace.allowed_pairs", "pairs of link names"),
    ],
)
def test_workspace_table_is_validated(tmp_path, table, key, expected):
    path = tmp_path / "bad.toml"
    path.write_text(f"[workspace]\n{table}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=expected) as info:
        load_config(path)
    assert info.value.key == key


def test_allowed_pairs_are_not_checked(tmp_path, capsys):
    """The UR5 folding its elbow (the collision test above) with the colliding pairs the
    oracle finds allowed in [workspace]: check names no collision."""
    reference = (
        "amplitude = [0, 0, 0.4, 0, 0, 0]\nfrequency = 0.1\n"
        "offset = [0, -1.5708, 2.7, -1.5708, 0, 0]"
    )
    oracle = Oracle("ur5")
    pairs = set()
    for tk in np.arange(0.0, 5.0 + 1e-9, 0.01):
        q = [0.0, -1.5708, 2.7 + 0.4 * math.sin(0.2 * math.pi * tk), -1.5708, 0.0, 0.0]
        oracle.pose(dict(zip(UR_JOINTS, q, strict=True)))
        pairs |= oracle.collisions()
    assert pairs
    path = _ur5_config(tmp_path, reference)
    listed = ", ".join(f'["{a}", "{b}"]' for a, b in sorted(pairs))
    text = Path(path).read_text(encoding="utf-8") + f"allowed_pairs = [{listed}]\n"
    Path(path).write_text(text, encoding="utf-8")
    main(["check", path, "--no-engine"])
    out = capsys.readouterr().out
    assert "collide" not in out.replace("no two links collide", ""), out
    assert "no two links collide" in out


def test_init_bad_plane_flags_exit_2(tmp_path, capsys):
    assert main(["init", "ur5", "--margin", "-1", "--out", str(tmp_path / "x.toml")]) == 2
    assert "--margin" in capsys.readouterr().err
