"""Configs that can be moved: a relative ``robot.urdf`` is relative to the config file's
folder; one that is not there is one line naming the config file, the key, the path tried
and what to write instead."""

from __future__ import annotations

import shutil

import pytest

from hmpc_pin import load_config
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError

from .conftest import CONFIGS


def test_a_config_moved_with_its_urdf_next_to_it_runs(tmp_path):
    """A relative path is resolved against the config's folder, wherever it is run from."""
    shutil.copy(CONFIGS.parent / "robots" / "planar3.urdf", tmp_path / "arm.urdf")
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    cfg = tmp_path / "sub" / "moved.toml"
    cfg.parent.mkdir()
    cfg.write_text(text.replace('urdf = "../robots/planar3.urdf"', 'urdf = "../arm.urdf"'))
    assert load_config(cfg).robot.urdf == (tmp_path / "arm.urdf").resolve()


def test_a_copied_shipped_config_names_the_file_the_key_and_model(tmp_path, capsys,
                                                                  monkeypatch):  # fmt: skip
    cfg = tmp_path / "mine.toml"
    shutil.copy(CONFIGS / "paper_combined.toml", cfg)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as info:
        load_config(cfg)
    message = str(info.value)
    assert message.startswith(f"{cfg}: robot.urdf: '../robots/planar3.urdf' not found")
    assert f"tried {(tmp_path.parent / 'robots' / 'planar3.urdf').resolve()}" in message
    assert "relative to the config file's folder" in message
    assert 'write model = "planar3"' in message
    out = tmp_path / "out"
    assert main(["run", str(cfg), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "robot.urdf" in err[0] and str(cfg) in err[0]
    assert not out.exists()


def test_an_init_config_moved_with_its_urdf_says_where_the_urdf_is(tmp_path):
    """``init`` writes an absolute URDF path; moved together with its URDF, the config
    names the file next to it."""
    first, moved = tmp_path / "a", tmp_path / "b"
    first.mkdir()
    shutil.copy(CONFIGS.parent / "robots" / "planar3.urdf", first / "my_arm.urdf")
    assert main(["init", str(first / "my_arm.urdf"), "--out", str(first / "arm.toml")]) == 0
    shutil.move(first, moved)
    with pytest.raises(ConfigError, match=r"robot\.urdf: .*my_arm\.urdf' not found") as info:
        load_config(moved / "arm.toml")
    assert 'my_arm.urdf is next to the config: write urdf = "my_arm.urdf"' in str(info.value)
