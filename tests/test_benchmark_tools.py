"""The refactoring checks (benchmarks/tools/arrays_check.py, refactor_check.py) and their
shared part (saved_outputs.py), on runs made up here: a rerun equal to the record passes, a
change beyond the tolerance, a NaN where there was none, a changed completion fail."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.tools import arrays_check, refactor_check, saved_outputs
from hmpc_pin.sim.result import RESULT_ARRAYS


def _arrays(tau: float = 1.0, complete: bool = True) -> dict[str, np.ndarray]:
    out = {name: np.linspace(0.0, 2.0, 5) for name in RESULT_ARRAYS}
    out["tau"] = np.full(5, tau)
    out["complete"] = np.array(complete)
    return out


CHANGES = {
    "within the tolerance": (_arrays(1.0 + 1e-13), 0),
    "beyond the tolerance": (_arrays(1.0 + 1e-6), 1),
    "a NaN": (_arrays(np.nan), 1),
    "the completion": (_arrays(complete=False), 1),
}


def test_difference_is_relative_nan_aware_and_exact_for_other_kinds():
    a = np.array([100.0, np.nan, 1.0])
    assert saved_outputs.difference(a, a + np.array([1e-3, 0, 0])) == pytest.approx(1e-5)
    assert saved_outputs.difference(a, np.array([100.0, 2.0, 1.0])) == np.inf
    assert saved_outputs.difference(np.array([0.5]), np.array([0.25])) == 0.25  # scale 1
    assert saved_outputs.difference(np.array(True), np.array(False)) == np.inf
    assert saved_outputs.difference(np.array("a"), np.array("a")) == 0.0
    assert saved_outputs.difference(np.zeros(2), np.zeros(3)) == np.inf


@pytest.mark.parametrize("change", CHANGES)
def test_refactor_check_fails_on_a_change(tmp_path, monkeypatch, capsys, change):
    new, code = CHANGES[change]
    current = {"arrays": _arrays()}
    monkeypatch.setattr(refactor_check, "CONFIGS", [tmp_path / "made_up.toml"])
    monkeypatch.setattr(refactor_check, "run_config", lambda path: dict(current["arrays"]))
    monkeypatch.setattr(refactor_check, "run_sweep_rows", lambda: [{"rms": 0.5, "kind": "a"}])
    assert refactor_check.main(["record", str(tmp_path / "rec")]) == 0
    assert refactor_check.main(["compare", str(tmp_path / "rec"), "--tol", "1e-9"]) == 0
    current["arrays"] = new
    assert refactor_check.main(["compare", str(tmp_path / "rec"), "--tol", "1e-9"]) == code
    lines = capsys.readouterr().out.splitlines()
    assert lines[-3].startswith("FAIL made_up" if code else "ok   made_up"), lines


@pytest.mark.parametrize("change", CHANGES)
def test_arrays_check_fails_on_a_change(tmp_path, monkeypatch, capsys, change):
    new, code = CHANGES[change]
    current = {"arrays": _arrays()}
    monkeypatch.setattr(
        arrays_check, "runs", lambda duration: {"made_up@auto": lambda: dict(current["arrays"])}
    )
    assert arrays_check.main(["record", str(tmp_path / "rec")]) == 0
    assert arrays_check.main(["compare", str(tmp_path / "rec")]) == 0
    current["arrays"] = new
    assert arrays_check.main(["compare", str(tmp_path / "rec"), "--tol", "1e-12"]) == code
    lines = capsys.readouterr().out.splitlines()
    assert lines[-2].startswith("FAIL made_up" if code else "ok   made_up"), lines
