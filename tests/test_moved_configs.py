"""Configs that can be moved: a relative ``robot.urdf`` is relative to the config file's
folder; one that is not there is one line naming the config file, the key, the path tried
and what to write instead."""

from __future__ import annotations

import shutil
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

import hmpc_pin
from hmpc_pin import load_config
from hmpc_pin.apps.cli import main
from hmpc_pin.data import config_path
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config.write import write_config

from .conftest import CONFIGS


def test_a_config_moved_with_its_urdf_next_to_it_runs(tmp_path):
    """A relative path is resolved against the config's folder, wherever it is run from."""
    shutil.copy(CONFIGS.parent / "robots" / "planar3.urdf", tmp_path / "arm.urdf")
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    cfg = tmp_path / "sub" / "moved.toml"
    cfg.parent.mkdir()
    cfg.write_text(text.replace('model = "planar3"', 'urdf = "../arm.urdf"'))
    assert load_config(cfg).robot.urdf == (tmp_path / "arm.urdf").resolve()


#: How the packaged paper configs named their arm before 0.3 (users' copies keep this form).
OLD_FORM = 'urdf = "../robots/planar3.urdf"'


def test_the_packaged_configs_name_their_robot_by_model_not_by_a_path():
    """A packaged config copied anywhere runs: no path into the package's folders."""
    import tomllib

    for path in sorted(CONFIGS.glob("*.toml")):
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
        assert "urdf" not in raw.get("robot", {}) and "urdf" not in raw.get("plant", {}), path


def test_an_old_config_naming_the_packaged_urdf_by_a_relative_path_still_loads(tmp_path):
    """A user's copy of a pre-0.3 packaged config (``urdf = "../robots/planar3.urdf"``,
    kept beside a ``robots/`` folder as in a clone) loads as before."""
    (tmp_path / "robots").mkdir()
    shutil.copy(CONFIGS.parent / "robots" / "planar3.urdf", tmp_path / "robots")
    (tmp_path / "configs").mkdir()
    cfg = tmp_path / "configs" / "old.toml"
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    cfg.write_text(text.replace('model = "planar3"', OLD_FORM), encoding="utf-8")
    config = load_config(cfg)
    assert config.robot.urdf == (tmp_path / "robots" / "planar3.urdf").resolve()
    assert hmpc_pin.Experiment.from_config(config).robot.model.nv == 3


def test_a_copied_old_config_names_the_file_the_key_and_model(tmp_path, capsys, monkeypatch):
    cfg = tmp_path / "mine.toml"
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    cfg.write_text(text.replace('model = "planar3"', OLD_FORM), encoding="utf-8")
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


# ----------------------------------------------------- the configs the package writes
def _copied(path, folder):
    """``path`` copied alone into the new folder ``folder``."""
    folder.mkdir(parents=True)
    return Path(shutil.copy(path, folder / path.name))


def test_a_written_config_of_a_packaged_robot_names_it_by_model_and_runs_when_copied(
    tmp_path, monkeypatch
):
    """``write_config`` (``identify --out``, ``tune``) of a packaged config: the robot by
    ``model``, no path at all; copied alone elsewhere it loads and runs."""
    out = write_config(config_path("paper_friction"), {"controller.friction": {
        "viscous": 1.0, "coulomb": 0.5}}, tmp_path / "ff.toml")  # fmt: skip
    raw = tomllib.loads(out.read_text(encoding="utf-8"))
    assert raw["robot"]["model"] == "planar3" and "urdf" not in raw["robot"]
    copy = _copied(out, tmp_path / "elsewhere" / "deeper")
    monkeypatch.chdir(tmp_path / "elsewhere")
    config = load_config(copy)
    assert config.robot.source == "planar3" and config.controller.friction.coulomb == 0.5
    result = hmpc_pin.Experiment.from_config(
        replace(config, simulation=replace(config.simulation, duration=0.05))
    ).run()
    assert result.complete


def test_a_written_config_with_a_packaged_trajectory_carries_it_beside(tmp_path):
    """The packaged trajectory file of panda_trajectory is copied beside the written
    config and named by its file name: the two copied together load anywhere."""
    out = write_config(config_path("panda_trajectory"), {}, tmp_path / "mine.toml")
    raw = tomllib.loads(out.read_text(encoding="utf-8"))
    assert raw["reference"]["trajectory"]["file"] == "panda_trajectory.csv"
    csv = out.with_name("panda_trajectory.csv")
    assert csv.read_bytes() == (CONFIGS / "panda_trajectory.csv").read_bytes()
    moved = tmp_path / "b"
    moved.mkdir()
    shutil.copy(out, moved)
    shutil.copy(csv, moved)
    assert load_config(moved / "mine.toml").reference.trajectory.file == (
        moved / "panda_trajectory.csv"
    )


def test_a_written_config_of_a_users_urdf_names_it_absolutely(tmp_path):
    """A user's URDF (given relative in the source) is written by its absolute path: the
    written config copied to another folder still finds it."""
    user = tmp_path / "project"
    user.mkdir()
    shutil.copy(CONFIGS.parent / "robots" / "planar3.urdf", user / "arm.urdf")
    src = user / "arm.toml"
    text = (CONFIGS / "paper_combined.toml").read_text(encoding="utf-8")
    src.write_text(text.replace('model = "planar3"', 'urdf = "arm.urdf"'), encoding="utf-8")
    out = write_config(src, {}, tmp_path / "written.toml")
    raw = tomllib.loads(out.read_text(encoding="utf-8"))
    assert raw["robot"]["urdf"] == str((user / "arm.urdf").resolve())
    copy = _copied(out, tmp_path / "far" / "away")
    assert load_config(copy).robot.urdf == (user / "arm.urdf").resolve()


def test_identify_out_writes_a_config_that_runs_when_copied(tmp_path, capsys):
    """``hmpc-pin identify RUN --config paper_friction --out ff.toml`` (the guide's
    command), the file copied to another folder and run from there."""
    assert main(["run", "paper_friction", "--no-figures",
                 "--out", str(tmp_path / "id")]) == 0  # fmt: skip
    ff = tmp_path / "id" / "ff.toml"
    code = main(["identify", str(tmp_path / "id" / "paper_friction.npz"), "--config",
                 "paper_friction", "--out", str(ff)])  # fmt: skip
    assert code in (0, 1), capsys.readouterr().err
    assert 'model = "planar3"' in ff.read_text(encoding="utf-8")
    assert "site-packages" not in ff.read_text(encoding="utf-8")
    copy = _copied(ff, tmp_path / "other")
    assert main(["run", str(copy), "--duration", "0.05", "--no-figures",
                 "--out", str(tmp_path / "o")]) == 0  # fmt: skip
