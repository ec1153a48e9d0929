"""Ctrl-C during the command line's start-up: exit 130 at once, with one line.

While ``hmpc-pin`` starts (imports, reading the config, loading the URDF, building the
controller) nothing has been written, and the only process started is ``run``'s figure
process (:mod:`hmpc_pin.apps.figure_worker`, importing matplotlib beside the start-up),
which ends with the command by itself (the parent-death signal on Linux, its closed pipe
elsewhere), so a Ctrl-C needs no clean-up: :func:`guard` installs a SIGINT handler that
prints one line and ends the process with exit status 130 at once. A handler that ends the
process is the only reliable one here: a ``KeyboardInterrupt`` raised during an import is
swallowed by a library's ``except BaseException`` (trimesh, which yourdfpy imports, does
that) or aborts the process when it crosses compiled code.

The command ends the start-up (:func:`end`) just before its first side effect (an output
folder, a file, a process other than the figure process): from then on Ctrl-C raises
:class:`KeyboardInterrupt` again and the command stops the way it documents (what was
computed is written, the arm gets its safe torque). :func:`end` first imports the modules
whose import swallows Ctrl-C, so that no later import can.

The package's ``__init__`` imports this module first of all; when the process is the
command line (``hmpc-pin`` or ``python -m hmpc_pin``), the module's first statements install
the guard's handler before any import that runs code (:func:`_guard_first`), so that the
guard covers the package's own imports and this module's; library users never get a handler
installed.

After the start-up, a command that must not be interrupted in the middle of a write
keeps Ctrl-C back with :class:`DeferredInterrupt` and raises it between the writes.

This module imports nothing from the package (it runs before the package is imported).
"""

from __future__ import annotations

# os, sys and the builtin _signal are loaded by the interpreter's own start: importing them
# runs no code, so nothing before the guard's handler (:func:`_guard_first`) can be where a
# Ctrl-C lands, but the few statements of this module that install it
import _signal
import os
import sys

#: Exit status of a Ctrl-C (128 + SIGINT, the shell's convention).
EXIT_INTERRUPTED = 130

#: The line printed by a Ctrl-C during start-up.
LINE = "interrupted at start-up, before any run (nothing written)"


def _exit_now(signum, frame) -> None:  # pragma: no cover - runs in subprocess tests
    try:
        os.write(2, (LINE + "\n").encode())
    finally:
        os._exit(EXIT_INTERRUPTED)


def is_command_line() -> bool:
    """Whether this process is the ``hmpc-pin`` command (script or ``python -m hmpc_pin``)."""
    argv0 = os.path.basename(sys.argv[0]) if sys.argv else ""
    if argv0 in ("hmpc-pin", "hmpc-pin.exe"):
        return True
    names = ("hmpc_pin", "hmpc_pin.__main__")
    args = iter(list(getattr(sys, "orig_argv", ()))[1:])
    for arg in args:
        if arg == "-m":
            return next(args, None) in names
        if arg.startswith("-m"):
            return arg[2:] in names
        if arg in ("-X", "-W"):  # options taking a value
            next(args, None)
        elif arg == "-c" or not arg.startswith("-"):
            return False
    return False


def _guard_first() -> None:
    """The guard's handler, for the command line, before this module imports anything that
    runs code (its own imports of ``signal``, ``threading`` ... are interruptible); a Ctrl-C
    that lands before the handler is in place, while the process is tested for being the
    command line, ends it the same way (exit 130, one line, no traceback)."""
    try:
        if is_command_line():
            _signal.signal(_signal.SIGINT, _exit_now)
    except KeyboardInterrupt:
        if is_command_line():
            _exit_now(_signal.SIGINT, None)
        raise


_guard_first()

import contextlib  # noqa: E402  (after the guard: these imports run code)
import signal  # noqa: E402
import threading  # noqa: E402

#: Modules on a command's path whose import swallows a KeyboardInterrupt (``except
#: BaseException``), imported by :func:`end` while the guard holds. None today: the URDF
#: is checked with the standard library's XML parser, not yourdfpy (trimesh); a module
#: that swallows it and is imported after the start-up is caught by :data:`interrupted`.
SWALLOWING_IMPORTS: tuple[str, ...] = ()


#: Whether a Ctrl-C came after the start-up (:func:`end`). Set by the command line's
#: handler before it raises :class:`KeyboardInterrupt`, so that a Ctrl-C which a library
#: swallowed while the run was set up (``except BaseException`` around a lazy import) still
#: stops the run: the run's entry points call :func:`raise_if_interrupted`.
interrupted = False


def _interrupt(signum, frame) -> None:
    """The command line's SIGINT handler after the start-up: remember, then raise."""
    global interrupted
    interrupted = True
    raise KeyboardInterrupt


def was_interrupted() -> bool:
    """Whether a Ctrl-C came after the start-up (:data:`interrupted`)."""
    return interrupted


def raise_if_interrupted() -> None:
    """Raise :class:`KeyboardInterrupt` when a Ctrl-C came after the start-up, even one a
    library swallowed (nothing happens for library users: no handler is installed)."""
    if interrupted:
        raise KeyboardInterrupt


def _unraisable(unraisable) -> None:
    """``sys.unraisablehook`` of the command line after the start-up: a Ctrl-C whose
    ``KeyboardInterrupt`` Python could not raise (it arrived while a finalizer or a weakref
    callback ran, e.g. SQLAlchemy's under Optuna) is remembered in :data:`interrupted`,
    which the next run raises (:func:`raise_if_interrupted`), and not printed as an
    "Exception ignored" traceback; anything else goes to the hook it replaced."""
    if isinstance(unraisable.exc_value, KeyboardInterrupt) and interrupted:
        return
    _previous_unraisable(unraisable)


_previous_unraisable = sys.unraisablehook


def active() -> bool:
    """Whether the start-up guard is the SIGINT handler now."""
    return signal.getsignal(signal.SIGINT) is _exit_now


def guard():
    """Make Ctrl-C end the process at once (exit 130, one line); return the handler it
    replaced (``None`` outside the main thread, where no handler can be installed)."""
    global interrupted
    interrupted = False
    try:
        return signal.signal(signal.SIGINT, _exit_now)
    except ValueError:  # not the main thread
        return None


def end() -> None:
    """End the start-up: import :data:`SWALLOWING_IMPORTS` while the guard holds, then let
    Ctrl-C raise :class:`KeyboardInterrupt`, remembered in :data:`interrupted` (nothing
    changes when the guard is not set); a Ctrl-C Python could not raise is remembered, not
    printed (:func:`_unraisable`)."""
    global _previous_unraisable
    if not active():
        return
    import importlib

    for name in SWALLOWING_IMPORTS:
        with contextlib.suppress(ImportError):  # a dependency of the package
            importlib.import_module(name)
    signal.signal(signal.SIGINT, _interrupt)
    if sys.unraisablehook is not _unraisable:
        _previous_unraisable, sys.unraisablehook = sys.unraisablehook, _unraisable


def restore(previous) -> None:
    """Put back the handler :func:`guard` returned (at the end of an in-process ``main``)."""
    if previous is not None:
        with contextlib.suppress(ValueError):  # not the main thread
            signal.signal(signal.SIGINT, previous)
    if sys.unraisablehook is _unraisable:
        sys.unraisablehook = _previous_unraisable


class DeferredInterrupt:
    """Ctrl-C kept back while a command writes, raised between the writes (the package's
    one deferral of Ctrl-C; ``hmpc-pin tune`` keeps it away from its study's database).

    A ``KeyboardInterrupt`` raised inside an SQLite write of Optuna's storage leaves its
    transaction open: the next write (the trial marked failed, the report's reads) finds
    "database is locked" and the command ends with a traceback. While installed (a
    context manager; main thread only), SIGINT raises at once inside :meth:`evaluating`
    (work that writes nothing, e.g. a trial's sweep), and elsewhere is remembered and
    raised at the next :meth:`evaluating` or :meth:`check`, between writes. The raise
    goes through the handler it replaced when that is the command line's (which records
    the Ctrl-C in :data:`interrupted`, then raises).
    """

    def __init__(self):
        self.pending = False
        self._evaluating = False
        self._previous = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handler)
        return self

    def __exit__(self, *exc) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)

    def _raise(self, signum=signal.SIGINT, frame=None) -> None:
        previous = self._previous
        if callable(previous) and previous is not signal.default_int_handler:
            previous(signum, frame)  # the command line's handler: it records, then raises
        raise KeyboardInterrupt

    def _handler(self, signum, frame) -> None:
        if self._evaluating:
            self._raise(signum, frame)
        self.pending = True

    def check(self) -> None:
        """Raise :class:`KeyboardInterrupt` when a Ctrl-C was kept back."""
        if self.pending:
            self._raise()

    def evaluating(self, fn, *args):
        """``fn(*args)`` with Ctrl-C raised at once (after one kept back: before it)."""
        self.check()
        self._evaluating = True
        try:
            return fn(*args)
        finally:
            self._evaluating = False


#: Commands that run a 1 kHz loop against a robot: numpy's BLAS on one thread (its default
#: thread pool turned a 7x7 solve from 5 us into 38 us with 100 ms tails), set before numpy
#: is imported (:func:`single_threaded_blas`).
REALTIME_COMMANDS = ("franka",)


def single_threaded_blas() -> None:
    """One BLAS/OpenMP thread (``OPENBLAS_NUM_THREADS`` and the like, unless set): only
    before numpy is imported does it take effect."""
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")


def _command_word() -> str | None:
    """The command's first word not an option (``hmpc-pin franka ...`` → ``"franka"``)."""
    return next((a for a in sys.argv[1:] if not a.startswith("-")), None)


if is_command_line():  # first thing the package does when it is the command line
    guard()
    if _command_word() in REALTIME_COMMANDS:
        single_threaded_blas()
