"""Ctrl-C at the first instants of the command line, provoked deterministically: the SIGINT
is sent from inside ``hmpc_pin._startup``'s own start (one of its imports, or its test of
whether the process is the command line), before or while the guard is installed. The
contract of tests/test_interrupts.py holds there too: exit 130, the one line, no traceback.

Each run is a fresh interpreter that names itself ``hmpc-pin`` (``sys.argv[0]``) and plants
the SIGINT with the standard library's hooks only (an import finder on ``sys.meta_path``, or
a wrapper of ``os.path.basename``), before ``import hmpc_pin``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from hmpc_pin._startup import EXIT_INTERRUPTED, LINE

#: Sends SIGINT to itself when ``_startup`` imports the module TARGET (``_signal`` and
#: ``os`` only: ``signal`` itself must not be loaded before the package).
AT_IMPORT = """
import _signal, os, sys
class Hook:
    def find_spec(self, name, path=None, target=None):
        # only the guard's own import (an editable install's finder may import the same
        # module earlier, before any line of hmpc_pin runs: that is the interpreter's start)
        if name == TARGET and "hmpc_pin._startup" in sys.modules:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), _signal.SIGINT)
        return None
hook = Hook()
sys.meta_path.insert(0, hook)
sys.argv[0] = "hmpc-pin"
import hmpc_pin
print("not reached" if hook in sys.meta_path else "not interrupted")
"""

#: Sends SIGINT to itself from inside ``is_command_line`` (its call of os.path.basename).
AT_TEST = """
import _signal, os, sys
basename = os.path.basename
def once(p):
    os.path.basename = basename
    os.kill(os.getpid(), _signal.SIGINT)
    return basename(p)
os.path.basename = once
sys.argv[0] = "hmpc-pin"
import hmpc_pin
print("not interrupted")
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("target", ["contextlib", "signal", "threading"])
def test_ctrl_c_during_the_guards_own_imports_exits_130_with_one_line(target):
    code = f"TARGET = {target!r}\n" + AT_IMPORT
    assert "signal" not in _run("import sys; print(sorted(sys.modules))").stdout.split("'")
    proc = _run(code)
    if proc.stdout.strip() == "not reached":  # loaded before the package, by the installer's finder
        pytest.skip(f"{target} is imported before hmpc_pin runs in this installation")
    assert proc.returncode == EXIT_INTERRUPTED, proc.stderr
    assert proc.stderr.strip() == LINE, proc.stderr
    assert proc.stdout == ""


def test_ctrl_c_while_the_guard_tests_for_the_command_line_exits_130_with_one_line():
    proc = _run(AT_TEST)
    assert proc.returncode == EXIT_INTERRUPTED, proc.stderr
    assert proc.stderr.strip() == LINE, proc.stderr
    assert proc.stdout == ""


def test_a_library_user_keeps_a_ctrl_c_during_the_import():
    """Outside the command line the import installs no handler: the Ctrl-C stays Python's
    KeyboardInterrupt (the user's to catch), not an exit."""
    code = AT_IMPORT.replace('sys.argv[0] = "hmpc-pin"', "").replace(
        'import hmpc_pin\nprint("not reached" if hook in sys.meta_path else "not interrupted")',
        "try:\n    import hmpc_pin\nexcept KeyboardInterrupt:\n    print('kept')",
    )
    proc = _run("TARGET = 'signal'\n" + code)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["kept"], proc.stdout
