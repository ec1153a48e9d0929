"""The benchmark command runs (timings are never asserted: machines are noisy)."""

from __future__ import annotations

import pytest

from .conftest import ROOT


@pytest.mark.slow
def test_quick_benchmark_writes_its_report(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    from benchmarks.run import main

    out = tmp_path / "BENCHMARKS.md"
    assert main(["--quick", "--out", str(out)]) == 0
    text = out.read_text()
    for heading in ("## Machine and versions", "## Targets", "## Controller step"):
        assert heading in text
