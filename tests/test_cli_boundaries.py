"""Bad input a wheel user met, each refused at the boundary with one line (exit 2), and
small inconsistencies between commands: a duration too long for the memory, a recorded run
as a trajectory reference, ``check`` of a file that is not a config, warnings on stderr,
``init --list``, a run's files not replaced silently."""

from __future__ import annotations

import re

import numpy as np
import pytest

import hmpc_pin
from hmpc_pin.apps.cli import main
from hmpc_pin.exceptions import ConfigError


def _mem_available() -> float:
    """MemAvailable [bytes], read here independently of the package."""
    with open("/proc/meminfo", encoding="ascii") as f:
        return next(float(ln.split()[1]) * 1024 for ln in f if ln.startswith("MemAvailable:"))


def test_a_duration_too_long_for_the_memory_is_one_line_naming_the_option(tmp_path, capsys):
    """1e9 s at Ts = 0.01 s on 3 joints: 1e11 samples, far beyond any memory; before, a
    numpy MemoryError traceback (exit 1)."""
    out = tmp_path / "o"
    assert main(["run", "paper_combined", "--duration", "1e9", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --duration: 1e+09 s"), err
    assert "Traceback" not in err[0] and not out.exists()
    # the longest duration it names fills half the memory available: 8 bytes x (9 arrays
    # x 3 joints + t + step time) per sample, one sample per Ts = 0.01 s
    longest = float(re.search(r"at most ([\d.e+]+) s", err[0]).group(1))
    need = 8 * (9 * 3 + 2) * (longest / 0.01 + 1)
    assert need == pytest.approx(0.5 * _mem_available(), rel=0.2)


def test_the_library_refuses_the_same_duration_before_allocating():
    config = hmpc_pin.load_config("paper_combined")
    from dataclasses import replace

    config = replace(config, simulation=replace(config.simulation, duration=1e9))
    with pytest.raises(ConfigError, match=r"simulation\.duration: .* GB"):
        hmpc_pin.Experiment.from_config(config)
    ex = hmpc_pin.Experiment.from_config(hmpc_pin.load_config("paper_combined"))
    with pytest.raises(ConfigError, match=r"^duration: "):
        ex.run(duration=1e9)
