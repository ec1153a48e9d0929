"""The compiled core: the RK4 plant's period and the hierarchical MPC's step in C++.

The extension module ``hmpc_pin._core`` (the library ``hmpc_core`` in ``cpp/``, one unit
per concept, and its bindings in ``bindings/python/``, built by ``CMakeLists.txt``) is
compiled **when the package is built** -- ``pip install .``, ``pip install -e .`` or
``pip wheel .`` run CMake through scikit-build-core against the
Pinocchio and ProxSuite CMake packages of the build environment -- and ships in the platform
wheel. Nothing is compiled at run time: there is no compiler, cache or lock here, only an
import. The run-time requirements pin the very Pinocchio and ProxSuite versions the module was
built against; :func:`load` checks them again (``_core.build_info``), so that an environment
changed by hand fails with one message instead of a crash.

Every component is compiled and has no Python twin in the package (their numpy oracles are in
``tests/reference/``): the dynamics (``Dynamics``), the disturbance observer of Eq 13
(``NDO``), the joint QPs (``JointQPs``), the references with a closed form
(``SineReference``, ``PolynomialReference``), the disturbances of the paper
(``GaussianPulses``, ``CoulombViscousFriction``, ``DisturbanceSum``), the RK4 period
(``RK4``) and the hierarchical MPC's step composed of them (``HierarchicalStep``).

A part of the package that has a compiled form hands it over with ``loop_port()`` (``None``
when it has none, e.g. when :func:`replaced` says a method of it was replaced: the loops then
call the Python object through its port's trampoline).
``backend`` in ``[controller]`` and ``[plant]`` is deprecated since 0.3 and has no effect.
"""

from __future__ import annotations

import importlib
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

from ..exceptions import ConfigError, NativeError, PerformanceWarning

__all__ = [
    "BACKENDS",
    "available",
    "build",
    "build_info",
    "deprecated_backend",
    "load",
    "loop_port",
    "model_string",
    "replaced",
    "resolve_backend",
]


def replaced(obj: object, cls: type, *names: str) -> bool:
    """Whether any of ``obj``'s methods ``names`` is not ``cls``'s own: overridden by a
    subclass, or set on the instance (e.g. a test's spy). A part's compiled port would not
    call it, so the part then hands over no port (``loop_port()`` returns ``None``)."""
    return any(
        getattr(getattr(obj, name, None), "__func__", None) is not getattr(cls, name)
        for name in names
    )


def loop_port(part: object, *args: object) -> Any:
    """``part``'s compiled port for the compiled loop: its class's ``loop_port(*args)``, or
    ``None`` (no such method: the loop calls the part through Python).

    Looked up on the class, never through the instance: a wrapper that hands its other
    attributes on to a wrapped part (``__getattr__``) hands on no port, so the loop calls
    the wrapper itself and never goes around it.
    """
    own = getattr(type(part), "loop_port", None)
    return own(part, *args) if callable(own) else None


#: The values of ``backend`` (``[controller]``, ``[plant]``).
BACKENDS = ("auto", "native", "python")

_module: ModuleType | None = None
_error: NativeError | None = None
_warned = False


def load() -> ModuleType:
    """The compiled module ``hmpc_pin._core``.

    Raises:
        NativeError: It is not installed (a source tree used without ``pip install``), or it
            was built against other Pinocchio/ProxSuite versions than those installed.
    """
    global _module, _error
    if _module is not None:
        return _module
    if _error is not None:
        raise _error
    try:
        import pinocchio  # its shared libraries (libpinocchio_default, Boost) first
        import proxsuite

        module = importlib.import_module("hmpc_pin._core")
    except ImportError as exc:
        _error = NativeError(
            f"the compiled module hmpc_pin._core is not installed ({exc}); it is "
            "built with the package: run `pip install .` (or `pip install -e .`) in the "
            "source tree, or install the wheel"
        )
        raise _error from exc
    info = dict(module.build_info)
    found = {
        "pinocchio": pinocchio.__version__,
        "proxsuite": getattr(proxsuite, "__version__", info["proxsuite"]),
    }
    wrong = {k: v for k, v in found.items() if v != info[k]}
    if wrong:
        _error = NativeError(
            "the compiled module was built against "
            + ", ".join(f"{k} {info[k]}" for k in wrong)
            + " but this environment has "
            + ", ".join(f"{k} {v}" for k, v in wrong.items())
            + "; reinstall hmpc_pin (pip install --force-reinstall hmpc_pin) or install "
            "those versions"
        )
        raise _error
    _module = module
    return module


def build_info() -> dict[str, str]:
    """What the compiled module was built against and where it is.

    Keys ``pinocchio``, ``proxsuite``, ``compiler``, ``build_type`` and ``path``.

    Raises:
        NativeError: The module cannot be loaded (:func:`load`).
    """
    module = load()
    return {**dict(module.build_info), "path": str(module.__file__)}


def build(verbose: bool = False) -> Path:
    """Deprecated since 0.3: the module is built when the package is built.

    Returns the path of the installed module (nothing is compiled).
    """
    warnings.warn(
        "hmpc_pin.native.build() is deprecated since 0.3: the compiled core is built when "
        "the package is installed; use hmpc_pin.native.build_info()['path']",
        DeprecationWarning,
        stacklevel=2,
    )
    return Path(build_info()["path"])


def deprecated_backend(backend: str, key: str) -> None:
    """Check a ``backend`` option of version 0.2 (``[controller]``, ``[plant]``, or the
    ``backend`` argument of a controller or plant): deprecated since 0.3, without effect.

    Raises:
        ConfigError: ``backend`` is not one of :data:`BACKENDS`.

    Warns:
        DeprecationWarning: ``"python"``, which asked for a Python path that is gone.
    """
    if backend not in BACKENDS:
        raise ConfigError(key, f"got {backend!r}; expected one of {BACKENDS}")
    if backend == "python":
        warnings.warn(
            f'{key} = "python" is deprecated since 0.3 and has no effect: the compiled core '
            "runs (a compensation written in Python still runs in Python); remove the key",
            DeprecationWarning,
            stacklevel=3,
        )


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
            f'the compiled core does not support mimic joints ({names}); use backend = "python"',
        )
    return robot.model.saveToString()


def available() -> bool:
    """Whether the compiled module loads here."""
    try:
        load()
    except NativeError:
        return False
    return True


def resolve_backend(backend: str, key: str, unsupported: str | None = None) -> bool:
    """Deprecated since 0.3 (nothing in the package asks any more: every component is
    compiled). Whether a component with option ``key = backend`` would run natively.

    Args:
        backend: ``"auto"``, ``"native"`` or ``"python"``.
        key: The option's dotted name, for messages (``"controller.backend"``).
        unsupported: Why this configuration has no compiled path (``None``: it has one).

    Raises:
        ConfigError: ``backend`` is not one of :data:`BACKENDS`, or ``"native"`` where the
            configuration has no compiled path.
        NativeError: ``"native"`` and the module cannot be loaded.
    """
    global _warned
    if backend not in BACKENDS:
        raise ConfigError(key, f"got {backend!r}; expected one of {BACKENDS}")
    if backend == "python":
        return False
    if unsupported is not None:
        if backend == "native":
            raise ConfigError(
                key, f'"native" does not support {unsupported}; use "auto" or "python"'
            )
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
                "to silence this)",
                PerformanceWarning,
                stacklevel=3,
            )
        return False
    return True
