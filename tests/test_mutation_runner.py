"""The mutation campaigns' runner (benchmarks/tools/mutation.py) on files made up here, and
the two campaigns' lists against the code as it is: every mutant's text is in its file,
once (a mutant whose code moved is retargeted or dropped with its reason, not skipped)."""

from __future__ import annotations

import pytest

from benchmarks.tools import mutants_cpp, mutation, one_line_mutants


def _tree(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "a.py").write_text("x = 1\ny = 2\ny = 2\n", encoding="utf-8")
    return tmp_path


def test_a_mutant_runs_applied_and_its_file_is_put_back(tmp_path, capsys):
    root = _tree(tmp_path)
    seen = []

    def run(mutant):
        seen.append((root / "pkg" / "a.py").read_text(encoding="utf-8"))
        return "killed", "1 failed"

    mutants = [("g", "pkg/a.py", "x = 1", "x = 0", ["t"])]
    assert mutation.campaign(mutants, [0], run, root=root) == 0
    assert seen == ["x = 0\ny = 2\ny = 2\n"]
    assert (root / "pkg" / "a.py").read_text(encoding="utf-8") == "x = 1\ny = 2\ny = 2\n"
    out = capsys.readouterr().out
    assert "#000 killed" in out and "g: 1 of 1 killed (100 %)" in out


def test_a_file_is_put_back_when_the_run_fails(tmp_path):
    root = _tree(tmp_path)

    def run(mutant):
        raise RuntimeError("the runner broke")

    with pytest.raises(RuntimeError):
        mutation.campaign([("g", "pkg/a.py", "x = 1", "x = 0", [])], [0], run, root=root)
    assert (root / "pkg" / "a.py").read_text(encoding="utf-8") == "x = 1\ny = 2\ny = 2\n"


@pytest.mark.parametrize(
    ("file", "old", "why"),
    [
        ("pkg/a.py", "z = 3", "occurs 0 times"),
        ("pkg/a.py", "y = 2", "occurs 2 times"),
        ("pkg/gone.py", "x = 1", "no such file"),
    ],
)
def test_a_mutant_whose_text_is_not_there_once_is_an_error_not_a_skip(
    tmp_path, capsys, file, old, why
):
    root = _tree(tmp_path)
    ran = []
    mutants = [("g", file, old, "", ["t"]), ("g", "pkg/a.py", "x = 1", "x = 0", ["t"])]
    code = mutation.campaign(mutants, [0, 1], lambda m: ran.append(m) or ("SURVIVED", ""),
                             root=root)  # fmt: skip
    assert code == 1
    assert ran == [mutants[1]]  # the others still run
    out = capsys.readouterr().out
    assert f"#000 ERROR    {file}" in out and why in out, out
    assert "g: 0 of 1 killed (0 %), 1 error(s)" in out, out
    assert (root / "pkg" / "a.py").read_text(encoding="utf-8") == "x = 1\ny = 2\ny = 2\n"


def test_check_runs_nothing(tmp_path, capsys):
    root = _tree(tmp_path)
    mutants = [("g", "pkg/a.py", "x = 1", "x = 0", []), ("g", "pkg/a.py", "z", "", [])]
    assert mutation.campaign(mutants, [0, 1], None, check=True, root=root) == 1
    assert "1 of 2 targets found once" in capsys.readouterr().out


@pytest.mark.parametrize("campaign", [one_line_mutants, mutants_cpp])
def test_every_mutant_names_text_in_its_file_once(campaign):
    problems = [(i, p) for i, m in enumerate(campaign.MUTANTS) if (p := mutation.target_problem(m))]
    assert problems == [], problems
