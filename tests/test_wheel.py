"""The platform wheel: built by ``pip wheel .``, installed into a fresh environment where no
compiler is reachable, and run from an empty folder.

This is what a user of the wheel gets: the compiled core inside it, loaded with no compiler,
no build cache and no source tree. The fresh environment installs the wheel with its
dependencies from the package index (so the exact Pinocchio and ProxSuite pins resolve), its
``PATH`` holds only its own ``bin/``, ``CC``/``CXX`` point nowhere, and the test first proves
that no C or C++ compiler can be found from there. The runs are the paper's combined
experiment with ``backend = "native"`` on both the controller and the plant (an error, not a
fallback, if the compiled module did not load), ``hmpc-pin run paper_combined`` as a user
types it, ``hmpc-pin reproduce``, the packaged configs listed and one copied and run, an
example script copied and run, and the README's quick commands.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import venv
import zipfile

import numpy as np
import pytest

from .conftest import ROOT

COMPILERS = ("cc", "gcc", "c++", "g++", "clang", "clang++")

SMOKE = """
import shutil, warnings
from dataclasses import replace
found = [c for c in {compilers!r} if shutil.which(c)]
assert not found, f"a compiler is reachable: {{found}}"
import hmpc_pin
from hmpc_pin import native
info = native.build_info()
config = hmpc_pin.load_config("paper_combined")
config = replace(config, controller=replace(config.controller, backend="native"),
                 plant=replace(config.plant, backend="native"))
with warnings.catch_warnings():
    warnings.simplefilter("error", hmpc_pin.PerformanceWarning)
    ex = hmpc_pin.Experiment.from_config(config)
    plant = ex.make_plant()
    result = ex.run()
assert ex.controller.native and plant.native and result.complete
print("package", hmpc_pin.__file__)
print("core", info["path"])
"""


def _run(cmd, **kw):
    out = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert out.returncode == 0, f"{cmd}\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


@pytest.mark.slow
def test_the_wheel_runs_from_an_empty_folder_with_no_compiler(tmp_path):
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(dist)],
         timeout=1800)  # fmt: skip
    (wheel,) = dist.glob("hmpc_pin-*.whl")
    assert "-none-any" not in wheel.name  # a platform wheel
    names = zipfile.ZipFile(wheel).namelist()
    for name in ("hmpc_pin/data/robots/planar3.urdf", "hmpc_pin/data/configs/paper_combined.toml",
                 "hmpc_pin/data/configs/panda_trajectory.csv", "hmpc_pin/examples/track_sine.py",
                 "hmpc_pin/py.typed"):  # fmt: skip
        assert name in names
    assert any(n.startswith("hmpc_pin/_core") and n.endswith((".so", ".pyd"))
               for n in names)  # fmt: skip
    assert not any(n.endswith((".cpp", ".hpp")) for n in names)

    env_dir = tmp_path / "env"
    venv.create(env_dir, with_pip=True)
    bindir = env_dir / "bin"
    _run([str(bindir / "python"), "-m", "pip", "install", "-q", str(wheel)], timeout=1800)
    empty = tmp_path / "empty"
    empty.mkdir()
    clean = {"PATH": str(bindir), "HOME": str(tmp_path), "CC": "/nonexistent/cc",
             "CXX": "/nonexistent/c++", "MPLBACKEND": "Agg"}  # fmt: skip
    for key in ("TMPDIR", "LANG"):
        if key in os.environ:
            clean[key] = os.environ[key]
    out = _run([str(bindir / "python"), "-c", SMOKE.format(compilers=COMPILERS)], cwd=empty,
               env=clean, timeout=600)  # fmt: skip
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines())
    assert lines["package"].startswith(str(env_dir)), lines
    assert lines["core"].startswith(str(env_dir)), lines

    # The commands a user types, from the empty folder.
    out = _run([str(bindir / "hmpc-pin"), "run", "paper_combined", "--out", "first"],
               cwd=empty, env=clean, timeout=600)  # fmt: skip
    assert "slower Python path" not in out.stderr
    with np.load(empty / "first" / "paper_combined.npz") as data:
        assert bool(data["complete"])
    _run([str(bindir / "hmpc-pin"), "reproduce", "--out", "rep", "--quiet"], cwd=empty,
         env=clean, timeout=900)  # fmt: skip
    assert "paper_combined" in (empty / "rep" / "report.md").read_text(encoding="utf-8")

    # What the wheel ships, with no clone: the packaged configs listed, one copied with its
    # trajectory file and run from the copy, an example copied and run with python.
    hmpc = str(bindir / "hmpc-pin")
    out = _run([hmpc, "configs"], cwd=empty, env=clean, timeout=300)
    assert "panda_trajectory" in out.stdout and "Paper Section 5.3" in out.stdout
    _run([hmpc, "configs", "copy", "panda_trajectory", "--out", "mine/traj.toml"], cwd=empty,
         env=clean, timeout=300)  # fmt: skip
    assert (empty / "mine" / "panda_trajectory.csv").is_file()
    _run([hmpc, "run", "mine/traj.toml", "--duration", "0.2", "--no-figures", "--out", "cp"],
         cwd=empty, env=clean, timeout=600)  # fmt: skip
    with np.load(empty / "cp" / "panda_trajectory.npz") as data:
        assert bool(data["complete"])
    _run([hmpc, "examples", "copy", "track_sine", "--out", "track_sine.py"], cwd=empty,
         env=clean, timeout=300)  # fmt: skip
    _run([str(bindir / "python"), "track_sine.py", "--out", "ex"], cwd=empty, env=clean,
         timeout=600)  # fmt: skip
    assert (empty / "ex" / "track_sine.npz").is_file()

    # The README's command line, as a wheel user types it (the long ones left out: a 200
    # sample sweep, a 60 s real-time run, a 30 trial study, a ROS node).
    for cmd in readme_commands():
        out = subprocess.run([str(bindir / cmd[0]), *cmd[1:]], cwd=empty, env=clean,
                             capture_output=True, text=True, timeout=900)  # fmt: skip
        # every one exits 0: the README's check is of a shipped config, which passes
        assert out.returncode == 0 and "Traceback" not in out.stderr, (cmd, out.stderr[-2000:])

    # The wheel's metadata: Project-URLs for the index page (the README's links are absolute).
    meta = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA")))
    assert b"Project-URL: Documentation, https://" in meta

    # A missing extra's hint installs it for this wheel (resolved, not installed: --dry-run).
    out = _run([str(bindir / "python"), "-c",
                "from hmpc_pin.exceptions import install_command; print(install_command('tune'))"],
               cwd=empty, env=clean, timeout=120)  # fmt: skip
    hint = out.stdout.strip()
    assert hint == f'pip install "hmpc_pin[tune] @ {wheel.resolve().as_uri()}"', hint
    args = shlex.split(hint)[2:]
    _run([str(bindir / "python"), "-m", "pip", "install", "--dry-run", "-q", *args], cwd=empty,
         env={**clean, "PATH": str(bindir)}, timeout=600)  # fmt: skip


#: README commands the wheel test runs (the others take minutes or a ROS 2 network).
QUICK = ("run", "compare", "init", "check", "identify")


def readme_commands() -> list[list[str]]:
    """The README's ``hmpc-pin`` commands of :data:`QUICK`, in order, comments dropped."""
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"## Command line\s+```bash\n(.*?)```", text, re.S).group(1)
    cmds = [shlex.split(line.split("#", 1)[0]) for line in block.splitlines()]
    return [c for c in cmds if len(c) > 1 and c[0] == "hmpc-pin" and c[1] in QUICK]


def test_the_readme_commands_the_wheel_test_runs_are_there():
    """The list the wheel test runs is the README's (a renamed command would drop out)."""
    assert [c[1] for c in readme_commands()] == ["run", "compare", "init", "check", "identify"]


def test_the_readmes_check_commands_exit_0(capsys):
    """Without building a wheel: each ``check`` of the README (a shipped config, which
    passes ``check``) exits 0, not 1 (the wheel test runs them from the wheel too)."""
    from hmpc_pin.apps.cli import main

    checks = [c for c in readme_commands() if c[1] == "check"]
    assert checks
    for cmd in checks:
        code = main(cmd[1:])  # as the README types it (with the engine comparison)
        assert code == 0, (cmd, capsys.readouterr())


def test_the_install_hint_of_a_clone_names_the_clone():
    """Run from this source tree (pyproject.toml and CMakeLists.txt beside the package):
    the hint installs the extra into the clone, editable."""
    from hmpc_pin.exceptions import install_command

    assert install_command("mujoco") == f'pip install -e "{ROOT.resolve()}[mujoco]"'


@pytest.mark.parametrize("record, wheel", [
    ({"archive_info": {}}, True),   # installed from the wheel file: that wheel again
    ({"dir_info": {}}, False),      # a file: URL pip did not record as an archive
    ({"archive_info": {}, "moved": True}, False),  # the wheel file is gone since
    (None, False),                  # no record (an index): the generic hint
])  # fmt: skip
def test_the_install_hint_of_an_installed_package_names_its_wheel(
    record, wheel, tmp_path, monkeypatch
):
    """Outside a clone the hint follows pip's record of where the package came from
    (PEP 610 direct_url.json): a wheel file that is still there is named by its URL."""
    import importlib.metadata
    import json

    import hmpc_pin.exceptions as exceptions

    whl = tmp_path / "hmpc_pin-0.3.0-cp311-cp311-linux_x86_64.whl"
    whl.write_bytes(b"PK")
    url = whl.as_uri()
    site = tmp_path / "site" / "hmpc_pin"
    site.mkdir(parents=True)
    monkeypatch.setattr(exceptions, "__file__", str(site / "exceptions.py"))

    class Dist:
        def read_text(self, name):
            assert name == "direct_url.json"
            return None if record is None else json.dumps({"url": url, **record})

    if record and record.get("moved"):
        whl.unlink()

    monkeypatch.setattr(importlib.metadata, "distribution", lambda name: Dist())
    hint = exceptions.install_command("ros")
    if wheel:
        assert hint == f'pip install "hmpc_pin[ros] @ {url}"'
    else:
        assert url not in hint and "hmpc_pin[ros] @ <the hmpc_pin wheel>" in hint


@pytest.mark.parametrize("beside", ["pyproject.toml", "CMakeLists.txt"])
def test_one_project_file_beside_the_package_is_not_a_clone(beside, tmp_path, monkeypatch):
    """A clone has both pyproject.toml and CMakeLists.txt beside the package; an installed
    package with only one of them beside it (a site folder inside another project) gets
    the generic hint, not an editable install of that folder."""
    import importlib.metadata

    import hmpc_pin.exceptions as exceptions

    site = tmp_path / "site" / "hmpc_pin"
    site.mkdir(parents=True)
    (site.parent / beside).write_text("")
    monkeypatch.setattr(exceptions, "__file__", str(site / "exceptions.py"))

    class Dist:
        def read_text(self, name):
            return None

    monkeypatch.setattr(importlib.metadata, "distribution", lambda name: Dist())
    hint = exceptions.install_command("ros")
    assert str(site.parent) not in hint and "hmpc_pin[ros] @ <the hmpc_pin wheel>" in hint
    assert 'in a clone, pip install -e ".[ros]"' in hint  # editable, from the clone's folder
