"""``hmpc-pin configs`` and ``hmpc-pin examples``: what a pip install ships, listed and
copied, the copies running where they are written (the wheel test runs them from a wheel)."""

from __future__ import annotations

import subprocess
import sys
import tomllib

import numpy as np
import pytest

from hmpc_pin.apps.cli import COMMANDS, build_parser, main

from .conftest import CONFIGS, ROOT


def test_configs_lists_every_packaged_config_with_its_description(capsys):
    assert main(["configs"]) == 0
    out = capsys.readouterr().out.splitlines()
    files = sorted(CONFIGS.glob("*.toml"))
    assert len(files) > 15
    for path in files:
        description = tomllib.loads(path.read_text(encoding="utf-8"))["description"]
        (line,) = [ln for ln in out if ln.split()[0] == path.stem]
        assert line.split(None, 1)[1].strip() == description


def test_configs_copy_writes_the_config_and_its_trajectory_and_the_copy_runs(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "mine" / "traj.toml"
    assert main(["configs", "copy", "panda_trajectory", "--out", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == (CONFIGS / "panda_trajectory.toml").read_text(
        encoding="utf-8"
    )  # comments kept: the file to edit
    csv = out.with_name("panda_trajectory.csv")
    assert csv.read_bytes() == (CONFIGS / "panda_trajectory.csv").read_bytes()
    capsys.readouterr()
    code = main(["run", str(out), "--duration", "0.1", "--no-figures", "--out", "o"])
    assert code == 0, capsys.readouterr().err
    with np.load(tmp_path / "o" / "panda_trajectory.npz") as data:
        assert bool(data["complete"]) and data["t"][-1] == pytest.approx(0.1)


def test_configs_copy_refuses_to_replace_without_force_and_names_unknown_configs(tmp_path, capsys):
    out = tmp_path / "pc.toml"
    out.write_text("mine\n")
    assert main(["configs", "copy", "paper_combined", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--force" in err[0] and out.read_text() == "mine\n"
    assert main(["configs", "copy", "paper_combined", "--out", str(out), "--force"]) == 0
    assert 'model = "planar3"' in out.read_text()
    assert main(["configs", "copy", "nosuch", "--out", str(tmp_path / "n.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "no packaged config 'nosuch'" in err[-1] and "paper_combined" in err[-1]


def test_examples_lists_and_copies_the_packaged_scripts(tmp_path, capsys):
    assert main(["examples"]) == 0
    listed = [ln.split()[0] for ln in capsys.readouterr().out.splitlines()[:-1]]
    assert listed == sorted(p.stem for p in (ROOT / "examples").glob("*.py"))
    out = tmp_path / "ts.py"
    assert main(["examples", "copy", "track_sine", "--out", str(out)]) == 0
    assert out.read_bytes() == (ROOT / "examples" / "track_sine.py").read_bytes()


def test_an_example_copied_out_of_the_package_runs_from_an_empty_folder(tmp_path):
    """The copy finds its config by the packaged name, not in a clone's folder."""
    out = tmp_path / "og.py"
    assert main(["examples", "copy", "observer_gain", "--out", str(out)]) == 0
    run = subprocess.run([sys.executable, str(out), "--gains", "50"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert "50" in run.stdout


def test_no_help_points_at_a_clones_folder():
    """A wheel has no configs/ folder: no command's help sends a user there."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in COMMANDS:
        text = sub.choices[name].format_help()
        assert "configs/" not in text and "examples/" not in text, name
    assert "packaged config" in sub.choices["run"].format_help()


def test_the_readme_links_absolutely_to_pages_that_exist():
    """The README is the wheel's long description (shown away from the repository): every
    link is absolute; a link into the documentation site names a page of docs/, a link
    into the repository a file of it; both sites are the pyproject's Project-URLs."""
    import re

    urls = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["urls"]
    docs, source = urls["Documentation"], urls["Source"]
    assert docs.startswith("https://") and source.startswith("https://github.com/")
    links = re.findall(r"\]\(([^)\s]+)\)", (ROOT / "README.md").read_text(encoding="utf-8"))
    assert len(links) > 15
    relative = [u for u in links if not u.startswith("https://")]
    assert not relative, relative
    for url in links:
        if url.startswith(docs):
            page = url[len(docs) :].removesuffix(".html")
            assert (ROOT / "docs" / f"{page}.md").is_file(), url
        elif url.startswith(source):
            path = re.sub(r"^/(blob|raw)/main/", "", url[len(source) :])
            assert (ROOT / path).is_file(), url
