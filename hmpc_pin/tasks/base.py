"""The reference protocol: what the controllers sample over their horizon.

A reference gives the joint angles and velocities the arm should follow. The
hierarchical MPC samples it at the :math:`N` future instants of its horizon,
:math:`t_k + jT_s,\\ j = 1..N`, every control period, so the protocol's main method is
vectorised over time:

``sample_many(times, out=None) -> (q_ref, dq_ref)``
    ``times`` of shape (m,) [s]; returns two arrays of shape (m, n) [rad, rad/s].
    With ``out = (q_buf, dq_buf)``, two C-contiguous float arrays of shape (m, n), the
    values are written into them (and they are returned): the controller's step then
    allocates nothing for the reference.

``sample(t) -> (q_ref, dq_ref)``
    one instant, two arrays of shape (n,).

Optional: ``loop_port()``, the compiled Reference port the step samples (``None``: sampled
in Python), or ``compiled_sampling() -> SineSampling | PolynomialSampling | None``, the
reference in a form the compiled step (:mod:`hmpc_pin.native`) samples in C++: a
:class:`SineSampling` (:math:`q = \\mathrm{offset} + \\mathrm{amplitude}\\,\\sin(\\omega t +
\\phi)`) or a :class:`PolynomialSampling` (segment :math:`i` = the number of breakpoints <=
t, :math:`[q\\ \\dot q] = \\sum_k c_{i,k}\\,s^k` with :math:`s = t - \\mathrm{origin}_i`). It
must give what ``sample_many`` gives (up to rounding; tested for the package's references);
``None`` (e.g. a subclass that samples otherwise) keeps the Python sampling.
:func:`compiled_sampling` decodes it, once, for the step (and the tuples of
``native_form()`` of 0.3, with a :class:`DeprecationWarning`); :func:`reference_port` is
what the step asks.

Every reference of the package implements both, vectorised. Anything else a user has
is adapted once, at the boundary, by :func:`as_reference`: an object with only
``sample(t)``, one whose ``sample_many`` takes no ``out``, or a plain callable
``f(t) -> (q, dq)``. Anything else raises :class:`~hmpc_pin.exceptions.InterfaceError`
naming what is missing.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DimensionError, InterfaceError, LimitError
from ..native import load as load_native
from ..native import loop_port

__all__ = [
    "PolynomialSampling",
    "Reference",
    "SineSampling",
    "as_reference",
    "check_limits",
    "check_reference_size",
    "compiled_sampling",
    "reference_port",
    "sample_horizon",
]

FloatArray = NDArray[np.float64]
Pair = tuple[FloatArray, FloatArray]


@runtime_checkable
class Reference(Protocol):
    """A joint-space reference :math:`r(t)`, :math:`\\dot r(t)` (module docstring)."""

    def sample(self, t: float) -> Pair:
        """Reference angle [rad] and velocity [rad/s] at ``t`` [s], each of shape (n,)."""
        ...

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        """Vectorised :meth:`sample` at ``times`` (m,) [s]: two arrays of shape (m, n);
        written into ``out`` when given."""
        ...


def _write(values: Pair, out: Pair | None) -> Pair:
    q, dq = np.asarray(values[0], dtype=float), np.asarray(values[1], dtype=float)
    if out is None:
        return q, dq
    if q.shape != out[0].shape or dq.shape != out[1].shape:
        raise DimensionError(
            f"reference.sample_many returned q_ref of shape {q.shape} and dq_ref of shape "
            f"{dq.shape} but {out[0].shape} (len(times), n joints) is needed; return two "
            f"arrays of shape ({out[0].shape[-1]},) from sample(t)"
        )
    out[0][...] = q
    out[1][...] = dq
    return out


@dataclass(frozen=True)
class SineSampling:
    """A sine per joint for the compiled reference (``cpp/src/references.cpp``):
    :math:`q = o + a\\sin(\\omega t + \\phi)`, :math:`\\dot q = (a\\omega)\\cos(\\omega t + \\phi)`.

    Attributes:
        omega: :math:`\\omega` [rad/s], (n,).
        phase: :math:`\\phi` [rad], (n,).
        amplitude: :math:`a` [rad], (n,).
        offset: :math:`o` [rad], (n,).
        amplitude_omega: :math:`a\\omega` [rad/s], (n,) (the velocity's amplitude, as
            computed by the reference).
    """

    omega: FloatArray
    phase: FloatArray
    amplitude: FloatArray
    offset: FloatArray
    amplitude_omega: FloatArray

    def port(self) -> Any:
        """The compiled reference (``hmpc_pin._core.SineReference``, the step's Reference
        port)."""
        return load_native().SineReference(
            self.omega, self.phase, self.amplitude, self.offset, self.amplitude_omega
        )

    def as_tuple(self) -> tuple[Any, ...]:
        """The tuple of ``native_form()`` (0.3): ``("sine", ω, φ, a, o, aω)``."""
        return ("sine", self.omega, self.phase, self.amplitude, self.offset, self.amplitude_omega)


@dataclass(frozen=True)
class PolynomialSampling:
    """A piecewise polynomial for the compiled reference (``cpp/src/references.cpp``): segment
    :math:`i` = the number of breakpoints <= t, :math:`[q\\ \\dot q] = \\sum_k c_{i,k}\\,s^k`
    with :math:`s = t - \\mathrm{origin}_i`.

    Attributes:
        breakpoints: :math:`t_k` [s], (K,), increasing.
        origins: The origin of each of the K + 1 segments [s], (K+1,).
        coefficients: :math:`c_{i,k}`, ((K+1)(d+1), 2n): row :math:`i(d+1) + k`, the
            columns :math:`[q\\ |\\ \\dot q]`.
        degree: :math:`d`.
    """

    breakpoints: FloatArray
    origins: FloatArray
    coefficients: FloatArray
    degree: int

    def port(self) -> Any:
        """The compiled reference (``hmpc_pin._core.PolynomialReference``, the step's
        Reference port)."""
        return load_native().PolynomialReference(
            self.breakpoints, self.origins, self.coefficients, self.degree
        )

    def as_tuple(self) -> tuple[Any, ...]:
        """The tuple of ``native_form()`` (0.3): ``("ppoly", t_k, origins, c, d)``."""
        return ("ppoly", self.breakpoints, self.origins, self.coefficients, self.degree)


#: A reference's form for the compiled sampler.
SamplingForm = SineSampling | PolynomialSampling


def compiled_sampling(reference: object) -> SamplingForm | None:
    """The form in which the compiled step samples ``reference`` itself, or ``None`` (it is
    sampled in Python): its ``compiled_sampling()``, or (0.3) the tuple of its
    ``native_form()`` decoded, with a :class:`DeprecationWarning`. The one place a
    reference's form is decoded."""
    own = getattr(reference, "compiled_sampling", None)
    if callable(own):
        form: SamplingForm | None = own()
        return form
    legacy = getattr(reference, "native_form", None)
    if not callable(legacy):
        return None
    warnings.warn(
        f"{type(reference).__name__}.native_form() is deprecated since 0.3; define "
        "compiled_sampling() returning a SineSampling or PolynomialSampling "
        "(hmpc_pin.tasks.base)",
        DeprecationWarning,
        stacklevel=2,
    )
    old = legacy()
    if old is None:
        return None
    if old[0] == "sine":
        return SineSampling(*old[1:])
    if old[0] == "ppoly":
        return PolynomialSampling(*old[1:])
    raise InterfaceError(
        old,
        "a native form ('sine', ...) or ('ppoly', ...)",
        f"{type(reference).__name__}.native_form() returned it; define compiled_sampling()",
    )


def reference_port(reference: object) -> Any:
    """The compiled Reference port of ``reference`` (its ``loop_port()``, or the port of its
    :func:`compiled_sampling` form), or ``None``: the step then samples it in Python."""
    if callable(getattr(type(reference), "loop_port", None)):  # its class's own port
        return loop_port(reference)
    form = compiled_sampling(reference)
    return None if form is None else form.port()


def samples_otherwise(cls: type, base: type) -> bool:
    """Whether the class ``cls`` (a subclass of ``base`` or ``base`` itself) overrides the
    sampling of ``base`` (its ``sample`` or ``sample_many`` method): then its samples are not
    the form ``base`` hands to the compiled step, which must call it instead."""
    return any(
        getattr(cls, name, None) is not getattr(base, name, None)
        for name in ("sample", "sample_many")
    )


class CompiledSampling:
    """Base of the references that a compiled reference evaluates (``cpp/src/references.cpp``):
    ``sample_many`` and ``sample`` are that one implementation, from ``_form()`` -- a
    :class:`SineSampling` or :class:`PolynomialSampling`, the same form the compiled step
    samples (``compiled_sampling``).
    """

    n: int
    _compiled: Any = None

    def _form(self) -> SamplingForm:
        raise NotImplementedError

    def _sampler(self) -> Any:
        sampler = self._compiled
        if sampler is None:
            sampler = self._form().port()
            self._compiled = sampler
        return sampler

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("_compiled", None)  # rebuilt on first use after unpickling
        return state

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        """Positions [rad] and velocities [rad/s] at ``times`` [s], each of shape
        ``times.shape + (n,)``, written into ``out`` when given (the
        :class:`Reference` protocol)."""
        t = np.asarray(times, dtype=float)
        flat = t.reshape(-1)
        shape = (flat.size, self.n)
        if (
            out is not None
            and t.ndim == 1
            and all(
                a.shape == shape
                and a.dtype == np.float64
                and a.flags.c_contiguous
                and a.flags.writeable
                for a in out
            )
        ):
            self._sampler().sample(flat, out[0], out[1])
            return out
        q, dq = np.empty(shape), np.empty(shape)
        self._sampler().sample(flat, q, dq)
        if t.ndim != 1:
            q, dq = q.reshape((*t.shape, self.n)), dq.reshape((*t.shape, self.n))
        return _write((q, dq), out)

    def sample(self, t: float) -> Pair:
        """Position [rad] and velocity [rad/s] at ``t`` [s], each of shape (n,)."""
        q, dq = self.sample_many(np.array([float(t)]))
        return q[0], dq[0]

    def compiled_sampling(self) -> SamplingForm | None:
        """``_form()`` for the compiled step; ``None`` for a subclass that samples otherwise
        (it overrides ``sample_many`` or ``sample``)."""
        if samples_otherwise(type(self), CompiledSampling):
            return None
        return self._form()

    def loop_port(self) -> Any:
        """The compiled reference the step samples its horizon from (the one that samples
        :meth:`sample_many` too); ``None`` for a subclass that samples otherwise."""
        return None if self.compiled_sampling() is None else self._sampler()

    def native_form(self) -> tuple[Any, ...] | None:
        """Deprecated since 0.3: :meth:`compiled_sampling` (typed) as the tuple of 0.3."""
        warnings.warn(
            "native_form() is deprecated since 0.3; call compiled_sampling()",
            DeprecationWarning,
            stacklevel=2,
        )
        form = self.compiled_sampling()
        return None if form is None else form.as_tuple()


class _ManyWithoutOut:
    """A reference whose ``sample_many(times)`` takes no ``out``: the values are copied."""

    def __init__(self, inner: object):
        self.inner = inner
        self._many = inner.sample_many  # type: ignore[attr-defined]
        self._one = getattr(inner, "sample", None)

    def sample(self, t: float) -> Pair:
        if self._one is not None:
            q, dq = self._one(t)
            return np.asarray(q, dtype=float), np.asarray(dq, dtype=float)
        q, dq = self._many(np.array([t], dtype=float))
        return np.asarray(q, dtype=float)[0], np.asarray(dq, dtype=float)[0]

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        return _write(self._many(times), out)

    def __getattr__(self, name: str) -> object:  # acceleration(t), n, ... of the inner one
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)


class _SampleOnly:
    """A reference with only ``sample(t)``: the horizon is sampled point by point."""

    def __init__(self, sample: Callable[[float], tuple[object, object]], inner: object):
        self._sample = sample
        self.inner = inner

    def sample(self, t: float) -> Pair:
        q, dq = self._sample(t)
        return np.asarray(q, dtype=float), np.asarray(dq, dtype=float)

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        pairs = [self._sample(float(t)) for t in np.asarray(times, dtype=float).reshape(-1)]
        q = np.array([p[0] for p in pairs], dtype=float)
        dq = np.array([p[1] for p in pairs], dtype=float)
        return _write((q, dq), out)

    def __getattr__(self, name: str) -> object:
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)


def _takes_out(method: Callable[..., object]) -> bool:
    try:
        params = inspect.signature(method).parameters
    except (TypeError, ValueError):  # builtins without a signature: call without out
        return False
    return "out" in params or any(p.kind is p.VAR_KEYWORD for p in params.values())


def as_reference(obj: object) -> Reference:
    """``obj`` as a :class:`Reference`, adapted once (module docstring).

    Returns ``obj`` itself when its ``sample_many`` takes ``out`` and it has ``sample``;
    an adapter otherwise (``acceleration`` and other members pass through).

    Raises:
        InterfaceError: ``obj`` has neither ``sample_many`` nor ``sample`` and is not
            callable.
    """
    many = getattr(obj, "sample_many", None)
    if callable(many):
        if callable(getattr(obj, "sample", None)) and _takes_out(many):
            return obj  # type: ignore[return-value]
        return _ManyWithoutOut(obj)
    one = getattr(obj, "sample", None)
    if callable(one):
        return _SampleOnly(one, obj)
    if callable(obj):
        return _SampleOnly(obj, obj)
    raise InterfaceError(
        obj,
        "a reference: it needs sample_many(times) -> (q, dq) of shape (len(times), n), "
        "or sample(t) -> (q, dq) of shape (n,), or to be a callable f(t) -> (q, dq)",
        "see hmpc_pin.tasks.base",
    )


def check_reference_size(reference: object, n: int, who: str) -> None:
    """Refuse a reference built for another number of joints than ``n``: one that says
    its size (attribute ``n``, as the package's references do) is checked when it is
    given; any other is checked on its first sample (the shapes it returns).

    Raises:
        DimensionError: ``reference.n`` differs from ``n``.
    """
    size = getattr(reference, "n", None)
    if isinstance(size, (int, np.integer)) and int(size) != n:
        raise DimensionError(
            f"{who}: the reference {type(reference).__name__} is for {int(size)} joints but "
            f"the robot has {n}; build it with one value per joint ({n})"
        )


def sample_horizon(reference: object, times: FloatArray) -> Pair:
    """Sample any reference (adapted by :func:`as_reference`) at ``times``: two (m, n) arrays."""
    q, dq = as_reference(reference).sample_many(np.asarray(times, dtype=float))
    return np.asarray(q, dtype=float), np.asarray(dq, dtype=float)


def check_limits(
    reference: object,
    lower: FloatArray,
    upper: FloatArray,
    times: FloatArray,
    joint_names: tuple[str, ...],
    *,
    tol: float = 1e-9,
) -> None:
    """Check that ``reference`` stays within ``[lower − tol, upper + tol]`` at ``times``.

    Raises:
        LimitError: Naming the first joint and time where the reference leaves its limits.
    """
    q_ref, _ = sample_horizon(reference, np.asarray(times, dtype=float))
    out = (q_ref < lower - tol) | (q_ref > upper + tol)
    if out.any():
        k, i = np.argwhere(out)[0]
        raise LimitError(
            "reference", joint_names[i], float(times[k]), float(q_ref[k, i]), lower[i], upper[i]
        )
