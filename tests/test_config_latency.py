"""``[controller] latency`` checked at the config boundary (:func:`hmpc_pin.checks.as_latency`):
a value the compiled core cannot hold is one message naming the key, the value and the
range, from the TOML loader and from the library's settings alike."""

from __future__ import annotations

import pytest

from hmpc_pin.apps.cli import main
from hmpc_pin.checks import MAX_LATENCY
from hmpc_pin.controllers import MPCSettings
from hmpc_pin.exceptions import ConfigError
from hmpc_pin.experiment.config import ControllerConfig

from .conftest import CONFIGS


@pytest.mark.parametrize("value", [1e300, MAX_LATENCY * (1 + 1e-9), -1e-3])
def test_a_latency_out_of_range_is_refused_naming_key_value_and_range(value):
    with pytest.raises(ConfigError, match="latency") as info:
        ControllerConfig(latency=value)
    message = str(info.value)
    assert "controller.latency" in message or message.startswith("latency")
    assert repr(value) in message
    with pytest.raises(ConfigError, match=r"MPCSettings\.latency"):
        MPCSettings(latency=value)


def test_the_largest_latency_loads():
    assert ControllerConfig(latency=MAX_LATENCY).latency == MAX_LATENCY


def test_a_huge_latency_in_a_file_exits_2_with_one_line(tmp_path, capsys):
    text = (CONFIGS / "paper_combined.toml").read_text()
    text = text.replace("Ts = 0.01 ", "latency = 1e300\nTs = 0.01 ", 1)
    urdf = (CONFIGS.parent / "robots" / "planar3.urdf").resolve().as_posix()
    path = tmp_path / "huge.toml"
    path.write_text(text.replace('model = "planar3"', f'urdf = "{urdf}"'))
    assert main(["run", str(path), "--duration", "0.05", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "controller.latency" in err[0] and "1e+300" in err[0]
    assert f"[0, {MAX_LATENCY:g}] s" in err[0]
    assert not list(tmp_path.glob("*.npz"))
