"""Native kernels: the RK4 plant's period and the hierarchical MPC's step in C++.

The Python path spends most of a control step in Python around Pinocchio and ProxSuite
(about thirty numpy calls per step, six per RK4 stage). This module compiles
``_core.cpp`` -- Pinocchio's CRBA, RNEA and ABA, ProxSuite's dense QP and Eigen's LU,
called from C++ on the matrices the Python side built -- into an extension module:

* on first use, with the C++ compiler of the machine (``$CXX``, else ``g++`` or
  ``clang++``) against the headers of the *installed* Pinocchio and ProxSuite (their cmeel
  prefix) and Eigen (``cmeel-eigen``, a dependency), so that the kernels evaluate the very
  model the Python bindings load;
* once per source and versions: the module is cached in ``$HMPC_PIN_CACHE`` (default
  ``$XDG_CACHE_HOME/hmpc_pin``, else ``~/.cache/hmpc_pin``) under a key made of the
  source, the compiler, the flags, Python's ABI and the Pinocchio, ProxSuite and Eigen
  versions; concurrent first uses (a sweep's workers) wait for one build (a file lock).

``hmpc-pin native --build`` builds it ahead (``make`` does), and prints the compiler's
output if it fails. The choice between the two paths is ``backend`` in ``[controller]``
and ``[plant]``: ``"auto"`` (native when it loads and supports the configuration, else
Python with one :class:`~hmpc_pin.exceptions.PerformanceWarning`), ``"native"`` (an
error when it cannot), ``"python"``.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import warnings
from pathlib import Path
from types import ModuleType

from ..exceptions import ConfigError, NativeError, PerformanceWarning

__all__ = [
    "BACKENDS",
    "available",
    "build",
    "cache_dir",
    "load",
    "model_string",
    "resolve_backend",
]

#: The values of ``backend`` (``[controller]``, ``[plant]``).
BACKENDS = ("auto", "native", "python")

HERE = Path(__file__).parent
#: The translation units, compiled in parallel (Pinocchio's part, ProxSuite's and the
#: binding), then linked into one module; and the header they share.
SOURCES = (HERE / "_dynamics.cpp", HERE / "_core.cpp")
HEADERS = (HERE / "_dynamics.hpp",)
FLAGS = [
    "-O3", "-DNDEBUG", "-std=c++17", "-fPIC", "-fvisibility=hidden",
    # Pinocchio's joint variant needs larger MPL lists (its CMake target sets these).
    "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
    "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
]  # fmt: skip

_module: ModuleType | None = None
_error: NativeError | None = None
_warned = False


def cache_dir() -> Path:
    """Where built modules are kept (``$HMPC_PIN_CACHE``, else the user cache)."""
    env = os.environ.get("HMPC_PIN_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        try:
            base = str(Path.home() / ".cache")
        except RuntimeError:  # no home directory (e.g. a service account)
            import tempfile

            base = tempfile.gettempdir()
    return Path(base) / "hmpc_pin"


def _compiler() -> str:
    for name in (os.environ.get("CXX"), "g++", "clang++", "c++"):
        if name and shutil.which(name):
            return str(shutil.which(name))
    raise NativeError("no C++ compiler found ($CXX, g++, clang++ or c++ on PATH)")


def _prefix_of(module: str, header: str) -> Path:
    """The install prefix whose ``include/`` holds ``header`` for an installed package."""
    spec = importlib.util.find_spec(module)
    origin = Path(spec.origin) if spec and spec.origin else None
    candidates = list(origin.parents) if origin else []
    candidates += [Path(sys.prefix), Path("/usr/local"), Path("/usr")]
    for prefix in candidates:
        if (prefix / "include" / header).exists():
            return prefix
    raise NativeError(f"the C++ headers of {module} ({header}) were not found")


def _paths() -> tuple[list[str], list[str], dict[str, str]]:
    """Include flags, link flags and the versions that key the cache."""
    import pinocchio
    import proxsuite

    pin_prefix = _prefix_of("pinocchio", "pinocchio/multibody.hpp")
    qp_prefix = _prefix_of("proxsuite", "proxsuite/proxqp/dense/dense.hpp")
    eigen = None
    for prefix in (pin_prefix, qp_prefix, Path(sys.prefix), Path("/usr/local"), Path("/usr")):
        if (prefix / "include" / "eigen3" / "Eigen" / "Core").exists():
            eigen = prefix / "include" / "eigen3"
            break
    if eigen is None:
        raise NativeError("the Eigen headers were not found (pip install cmeel-eigen)")
    try:
        import pybind11
    except ImportError as exc:
        raise NativeError("pybind11 is not installed (pip install pybind11)") from exc
    lib = pin_prefix / "lib"
    includes = [f"-I{pin_prefix / 'include'}", f"-I{qp_prefix / 'include'}", f"-I{eigen}",
                f"-I{pybind11.get_include()}", f"-I{sysconfig.get_paths()['include']}"]  # fmt: skip
    links = [f"-L{lib}", "-lboost_serialization", f"-Wl,-rpath,{lib}"]
    version_file = eigen / "Eigen" / "Version"
    versions = {
        "pinocchio": pinocchio.__version__,
        "proxsuite": getattr(proxsuite, "__version__", "?"),
        "eigen": version_file.read_text()[:400] if version_file.exists() else "?",
        "pybind11": pybind11.__version__,
    }
    return includes, links, versions


def _target() -> tuple[list[list[str]], list[str], Path]:
    """The compile commands (one per translation unit, writing ``{obj<i>}``), the link
    command (writing ``{out}``) and the module file they make (not yet built, maybe)."""
    cxx = _compiler()
    includes, links, versions = _paths()
    cxx_version = subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout
    key = hashlib.sha256()
    parts = [path.read_bytes() for path in (*SOURCES, *HEADERS)]
    parts += [cxx.encode(), cxx_version.encode(), " ".join(FLAGS).encode(),
              " ".join(includes + links).encode(), repr(sorted(versions.items())).encode(),
              sys.version.encode(), platform.machine().encode()]  # fmt: skip
    for part in parts:
        key.update(part)
        key.update(b"\0")
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    target = cache_dir() / f"native-{key.hexdigest()[:16]}" / f"_core{suffix}"
    compiles = [[cxx, *FLAGS, *includes, "-c", str(src), "-o", f"{{obj{i}}}"]
                for i, src in enumerate(SOURCES)]  # fmt: skip
    link = [cxx, "-shared", *(f"{{obj{i}}}" for i in range(len(SOURCES))), "-o", "{out}", *links]
    return compiles, link, target


def _fill(cmd: list[str], names: dict[str, str]) -> list[str]:
    for key, value in names.items():
        cmd = [part.replace("{" + key + "}", value) for part in cmd]
    return cmd


def build(verbose: bool = False) -> Path:
    """Build the module if it is not cached; return its path.

    The translation units compile in parallel (about 2 minutes on 2 cores here), then link.

    Args:
        verbose: Print the compiler commands and output.

    Raises:
        NativeError: No compiler or headers, or the compiler failed (its first error line;
            the whole output in ``build.log`` beside the module).
    """
    compiles, link, target = _target()
    if target.exists():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    with open(target.parent / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one build; the others wait and reuse it
        if target.exists():
            return target
        pid = os.getpid()
        names = {f"obj{i}": str(target.parent / f"{src.stem}.{pid}.o")
                 for i, src in enumerate(SOURCES)}  # fmt: skip
        names["out"] = str(target.with_name(f"{target.name}.{pid}.tmp"))
        if not verbose:  # a first run says why it pauses
            print(
                "hmpc_pin: compiling the native kernels once for this environment (a few "
                f"minutes; cached in {target.parent})...", file=sys.stderr, flush=True,
            )  # fmt: skip
        log = []
        try:
            jobs = [_fill(cmd, names) for cmd in compiles]
            procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      text=True) for cmd in jobs]  # fmt: skip
            results = [(cmd, *proc.communicate(), proc.returncode)
                       for cmd, proc in zip(jobs, procs, strict=True)]  # fmt: skip
            if all(code == 0 for *_, code in results):
                cmd = _fill(link, names)
                proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                      text=True)  # fmt: skip
                results.append((cmd, proc.stdout, None, proc.returncode))
            for cmd, out, _, code in results:
                log.append(" ".join(cmd) + f"\n{out or ''}(exit {code})\n")
                if verbose:
                    print(log[-1], flush=True)
            (target.parent / "build.log").write_text("\n".join(log))
            failed = [(out, code) for _, out, _, code in results if code != 0]
            if failed:
                out, code = failed[0]
                errors = [ln for ln in (out or "").splitlines() if "error" in ln]
                last = (errors or (out or "").strip().splitlines() or ["no output"])[0]
                raise NativeError(f"the compiler failed (exit {code}; its output is in "
                                  f"{target.parent / 'build.log'}): {last.strip()}")  # fmt: skip
            os.replace(names["out"], target)
        finally:
            for name in names.values():
                with contextlib.suppress(FileNotFoundError):
                    Path(name).unlink()
    return target


def load() -> ModuleType:
    """The native module, built on first use (:func:`build`).

    Raises:
        NativeError: It cannot be built or imported here.
    """
    global _module, _error
    if _module is not None:
        return _module
    if _error is not None:
        raise _error
    try:
        path = build()
        import pinocchio  # noqa: F401  (its shared libraries first)

        spec = importlib.util.spec_from_file_location("hmpc_pin.native._core", path)
        if spec is None or spec.loader is None:
            raise NativeError(f"cannot import {path}")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except NativeError as exc:
        _error = exc
        raise
    except (OSError, ImportError) as exc:
        _error = NativeError(f"{type(exc).__name__}: {exc}")
        raise _error from exc
    _module = module
    return module


def model_string(robot) -> str:
    """The serialized Pinocchio model of ``robot`` that the kernels load.

    Raises:
        ConfigError: The model has mimic joints (Pinocchio 4.1 restores them badly from a
            serialized model, and has no ABA for them): such a robot runs in Python.
    """
    if getattr(robot, "mimic_joints", None):
        names = ", ".join(robot.mimic_joints)
        raise ConfigError(
            "backend",
            f'the native kernels do not support mimic joints ({names}); use backend = "python"',
        )
    return robot.model.saveToString()


def available() -> bool:
    """Whether the native module builds and loads here."""
    try:
        load()
    except NativeError:
        return False
    return True


def resolve_backend(backend: str, key: str, unsupported: str | None = None) -> bool:
    """Whether a component with option ``key = backend`` runs natively.

    Args:
        backend: ``"auto"``, ``"native"`` or ``"python"``.
        key: The option's dotted name, for messages (``"controller.backend"``).
        unsupported: Why this configuration has no native path (``None``: it has one).

    Raises:
        ConfigError: ``backend`` is not one of :data:`BACKENDS`, or ``"native"`` where the
            configuration has no native path.
        NativeError: ``"native"`` and the module cannot be built or loaded.
    """
    global _warned
    if backend not in BACKENDS:
        raise ConfigError(key, f"got {backend!r}; expected one of {BACKENDS}")
    if backend == "python":
        return False
    if unsupported is not None:
        if backend == "native":
            raise ConfigError(key, f'"native" does not support {unsupported}; use "auto" '
                              'or "python"')  # fmt: skip
        return False
    if backend == "native":
        load()
        return True
    try:
        load()
    except NativeError as exc:
        if not _warned:
            _warned = True
            warnings.warn(
                f'{exc.reason}; running the slower Python path (set backend = "python" '
                "to silence this)", PerformanceWarning, stacklevel=3,
            )  # fmt: skip
        return False
    return True
