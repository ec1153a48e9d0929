"""Disturbances applied to the plant: friction (Eq 32), pulse (Eq 33), sum (Eq 34).

A disturbance is any callable ``d(t, q, dq) -> (n,)`` [N·m] added to the input
torque in Eq (1): :math:`M\\ddot q + C\\dot q + G = \\tau + d`. The classes here
support ``+`` to build sums, e.g. the paper's combined case (Eq 34)
``CoulombViscousFriction(a, b) + GaussianPulse(a_d, b_d, sigma)``.

Each hands the plant its Disturbance port (``cpp/include/hmpc/interfaces.hpp``) with
``loop_port(n)``: the friction and the pulses their compiled law
(``cpp/include/hmpc/disturbances.hpp``, the one implementation of each), a sum the compiled
sum of its terms' ports, a time-only term of the user's a port that calls its
``sample_times``; ``None`` (a callable of the user's, a term whose method was replaced) lets
the plant call it as ``d(t, q, dq)``. :func:`disturbance_port` is what a plant asks.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..exceptions import ConfigError, InterfaceError
from ..native import load as load_native
from ..native import loop_port, replaced

__all__ = [
    "CoulombViscousFriction",
    "Disturbance",
    "GaussianPulse",
    "Periodic",
    "SumDisturbance",
    "TimeOnly",
    "ZeroDisturbance",
    "as_disturbance",
    "disturbance_port",
]

DisturbanceFn = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


class Disturbance:
    """Base class: callable ``d(t, q, dq)`` with ``+`` for sums.

    Attributes:
        terms: The terms of the sum this disturbance is (itself for a single term).
    """

    @property
    def terms(self) -> tuple:
        """The summed terms (``(self,)`` for a single term, ``()`` for zero)."""
        return (self,)

    def __call__(self, t: float, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def __add__(self, other) -> Disturbance:
        other = as_disturbance(other)
        if isinstance(other, ZeroDisturbance):
            return self
        return SumDisturbance(self, other)

    def loop_port(self, n: int) -> Any:
        """The compiled Disturbance port of this term for ``n`` joints, or ``None``: the
        plant calls it as ``d(t, q, dq)`` (the default)."""
        return None


class ZeroDisturbance(Disturbance):
    """No disturbance: :math:`d = 0`."""

    def __init__(self, n: int):
        self.n = n

    def __call__(self, t, q, dq):
        return np.zeros(self.n)

    @property
    def terms(self) -> tuple:
        """No terms."""
        return ()

    def __add__(self, other) -> Disturbance:
        return as_disturbance(other)  # 0 + d = d: no zeros evaluated in the plant loop

    def loop_port(self, n: int) -> Any:
        """The empty compiled sum: nothing evaluated."""
        return load_native().DisturbanceSum([], n)


def _defined_by(cls, name: str) -> None:
    """Refuse a subclass that defines ``__call__`` of a term whose value is defined by
    ``name`` alone (a plant evaluates ``name`` compiled, inside its integration, so a
    ``__call__`` of its own would be a second definition the plant never sees)."""
    if "__call__" in vars(cls):
        raise InterfaceError(
            cls,
            f"a {cls.__mro__[1].__name__}: such a term is defined by {name}() alone (the "
            "plant evaluates that, compiled), but this class defines __call__",
            f"define {name}() instead, or subclass Disturbance for a term of your own",
        )


class TimeOnly(Disturbance):
    """A disturbance of time alone, :math:`d(t)` [N·m], defined by :meth:`sample_times`
    (``d(t, q, dq)`` is ``sample_times([t])[0]``): a plant tabulates it at every stage time
    of a chunk of periods at once (:class:`~hmpc_pin.sim.plants.RK4Plant`, MuJoCo).
    Subclasses define :meth:`sample_times`, not ``__call__``.
    """

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _defined_by(cls, "sample_times")

    def __call__(self, t, q, dq):
        return self.sample_times(np.array([float(t)]))[0]

    def sample_times(self, times: np.ndarray) -> np.ndarray:
        """The term at each of ``times`` (m,) [s]: (m, n) [N·m]."""
        raise NotImplementedError

    def loop_port(self, n: int) -> Any:
        """A time-only port that calls :meth:`sample_times` once per period, with the
        period's stage times."""
        return load_native().TimeOnlyTerm(self.sample_times, n)


class CoulombViscousFriction(Disturbance):
    """Friction opposing motion, Eq (32) with the physical sign (SPEC §3).

    .. math::  d_i = -(a_i \\dot q_i + b_i\\,\\mathrm{sgn}(\\dot q_i)), \\quad \\mathrm{sgn}(0) = 0

    The paper writes :math:`d = +F_r`; taken literally, friction feeds energy into the
    arm (negative ``viscous``/``coulomb`` give that reading; the config's
    ``[disturbance.friction] sign = "literal"``). Measured (docs, "Decisions"): the
    literal reading fails without the observer and with it settles only after 0.5 s, so
    friction opposing motion is the default.

    Args:
        viscous: a [N·m·s/rad], shape (n,) (paper: 10, 8, 5).
        coulomb: b [N·m], shape (n,) (paper: 3.0, 2.4, 1.8).
    """

    def __init__(self, viscous, coulomb):
        self.viscous = np.asarray(viscous, dtype=float)
        self.coulomb = np.asarray(coulomb, dtype=float)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _defined_by(cls, "friction_coefficients")

    def __call__(self, t, q, dq):
        dq = np.asarray(dq, dtype=float)  # the compiled law (joint_dynamics.hpp), per joint
        a, b = (np.broadcast_to(c, dq.shape) for c in self.friction_coefficients())
        return -load_native().joint_torque(a, b, dq)

    def friction_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """``(a, b)`` with :math:`d = -(a\\dot q + b\\,\\mathrm{sgn}\\,\\dot q)`, the term's
        one definition (``d(t, q, dq)`` is the law of these): a plant evaluates the term
        compiled, inside its integration (:class:`~hmpc_pin.sim.plants.RK4Plant`)."""
        return self.viscous, self.coulomb

    def loop_port(self, n: int) -> Any:
        """The compiled friction of these coefficients for ``n`` joints; ``None`` for
        coefficients of another shape (its own call then raises its error)."""
        a, b = (np.asarray(c, dtype=float) for c in self.friction_coefficients())
        if a.shape not in ((), (n,)) or b.shape not in ((), (n,)):
            return None
        a, b = (np.broadcast_to(c, (n,)).astype(float) for c in (a, b))
        return load_native().CoulombViscousFriction(a, b)


class GaussianPulse(TimeOnly):
    """Gaussian-shaped external torque, Eq (33).

    .. math::  d_i = a_i \\exp\\left(-\\frac{(t - b_i)^2}{2\\sigma_i^2}\\right)

    Args:
        amplitude: a [N·m] (paper: 10, 8, 0.3).
        center: b [s] (paper: 1, 2, 3).
        sigma: σ [s] (paper: 0.3).
    """

    def __init__(self, amplitude, center, sigma):
        self.amplitude = np.asarray(amplitude, dtype=float)
        self.center = np.asarray(center, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)

    def _law(self, n: int) -> Any:
        """The compiled law (``cpp/src/disturbances.cpp``, the one implementation of Eq 33)
        of these parameters, broadcast to ``n`` joints."""
        a, b, s = (
            np.broadcast_to(x, (n,)).astype(float)
            for x in (self.amplitude, self.center, self.sigma)
        )
        return load_native().GaussianPulses(a, b, s)

    def sample_times(self, times: np.ndarray) -> np.ndarray:
        """The pulse at each of ``times`` (m,) [s]: (m, n) [N·m] (n: the parameters'
        broadcast length), by the compiled law."""
        params = (self.amplitude, self.center, self.sigma)
        shape = np.broadcast_shapes(*(np.shape(x) for x in params))
        n = shape[0] if shape else 1
        return self._law(n).at_times(np.asarray(times, dtype=float).reshape(-1), n)

    def loop_port(self, n: int) -> Any:
        """The compiled pulses for ``n`` joints; a subclass or an instance that samples
        otherwise (:meth:`sample_times` replaced), or parameters of another shape, get the
        time-only port that calls :meth:`sample_times`."""
        shapes = {np.shape(x) for x in (self.amplitude, self.center, self.sigma)}
        if replaced(self, GaussianPulse, "sample_times") or not shapes <= {(), (n,)}:
            return super().loop_port(n)
        return self._law(n)


class SumDisturbance(Disturbance):
    """Sum of disturbances, e.g. Eq (34): :math:`d = F_r(\\dot q) + \\tau_d(t)`."""

    def __init__(self, *terms: DisturbanceFn):
        flat: list[DisturbanceFn] = []
        for term in terms:  # (a + b) + c is stored flat as (a, b, c)
            flat.extend(term.terms if isinstance(term, SumDisturbance) else (term,))
        self._terms = tuple(flat)

    @property
    def terms(self) -> tuple:
        """The summed terms, flat."""
        return self._terms

    def __call__(self, t, q, dq):
        terms = self.terms
        total = np.array(terms[0](t, q, dq), dtype=float)  # own copy: terms may return theirs
        for term in terms[1:]:
            total += term(t, q, dq)
        return total

    def loop_port(self, n: int) -> Any:
        """The compiled sum of the terms' ports (:func:`disturbance_port`), in their order."""
        return load_native().DisturbanceSum([disturbance_port(t, n) for t in self.terms], n)


class Periodic(Disturbance):
    """A disturbance repeated every ``period`` seconds: :math:`d(t \\bmod T, q, \\dot q)`.

    Used by long runs (``benchmarks/studies/long_run.py``) so that the paper's pulses, which
    happen once in the first seconds, come back every minute. State-dependent terms
    (friction) are unchanged by the wrapping.
    """

    def __init__(self, disturbance: DisturbanceFn, period: float):
        if not (np.isfinite(period) and period > 0):
            raise ConfigError("period", f"got {period!r}; expected a finite number > 0 [s]")
        self.disturbance = disturbance
        self.period = float(period)

    def __call__(self, t, q, dq):
        return self.disturbance(t % self.period, q, dq)


class _Callable(Disturbance):
    def __init__(self, fn: DisturbanceFn):
        self.fn = fn

    def __call__(self, t, q, dq):
        return np.asarray(self.fn(t, q, dq), dtype=float)


def disturbance_port(d, n: int) -> Any:
    """What a plant of ``n`` joints evaluates for the disturbance ``d``: its compiled port
    (``d.loop_port(n)``), or ``d`` itself when it has none (called as ``d(t, q, dq)``)."""
    port = loop_port(d, n)
    return d if port is None else port


def as_disturbance(d) -> Disturbance:
    """Wrap a user callable ``d(t, q, dq)`` so it supports ``+``."""
    if isinstance(d, Disturbance):
        return d
    if not callable(d):
        raise InterfaceError(d, "a disturbance: callable as d(t, q, dq) -> (n,) [N·m]")
    return _Callable(d)
