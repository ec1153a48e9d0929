"""The sine reference of the paper, Eq (31)."""

from __future__ import annotations

import numpy as np

from .base import FloatArray, Pair, _write

__all__ = ["SineReference"]


def _flat_views_ok(out: Pair, shape: tuple[int, int]) -> bool:
    """Whether ``out`` holds two C-contiguous float arrays of ``shape`` (written in place)."""
    return all(a.shape == shape and a.dtype == np.float64 and a.flags.c_contiguous for a in out)


class SineReference:
    """:math:`r_i(t) = o_i + a_i\\sin(2\\pi f_i t + \\phi_i)`, Eq (31).

    The paper's reference is ``SineReference(n=3)``: :math:`r_i = \\sin(0.2\\pi t)`,
    :math:`\\dot r_i = 0.2\\pi\\cos(0.2\\pi t)`.

    Args:
        n: Number of joints.
        amplitude: a [rad], scalar or (n,).
        frequency: f [Hz], scalar or (n,) (paper: 0.1 Hz = 0.2π rad/s).
        offset: o [rad], scalar or (n,).
        phase: φ [rad], scalar or (n,).
    """

    def __init__(self, n: int, amplitude=1.0, frequency=0.1, offset=0.0, phase=0.0):
        self.n = int(n)
        shape = (self.n,)
        self.amplitude = np.broadcast_to(np.asarray(amplitude, float), shape).copy()
        self.omega = 2.0 * np.pi * np.broadcast_to(np.asarray(frequency, float), shape)
        self.offset = np.broadcast_to(np.asarray(offset, float), shape).copy()
        self.phase = np.broadcast_to(np.asarray(phase, float), shape).copy()
        self._amp_omega = self.amplitude * self.omega
        self._tiles: dict[int, tuple[np.ndarray, ...]] = {}
        self._out: Pair | None = None
        self._out_flat: Pair = (np.empty(0), np.empty(0))

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference angle [rad] and velocity [rad/s] at time ``t`` [s]."""
        arg = self.omega * t + self.phase
        return self.offset + self.amplitude * np.sin(arg), self._amp_omega * np.cos(arg)

    def sample_many(self, times: FloatArray, out: Pair | None = None) -> Pair:
        """Vectorised :meth:`sample` (the :class:`~hmpc_pin.tasks.base.Reference` protocol).

        Args:
            times: Instants [s], shape (m,).
            out: Optional ``(q_buf, dq_buf)``, C-contiguous float arrays of shape (m, n)
                to write into (the controller's horizon stack).

        Returns:
            ``(q_ref, dq_ref)`` [rad, rad/s], each of shape (m, n).
        """
        times = np.asarray(times, dtype=float)
        if times.ndim != 1:
            return _write(self._sample_many_broadcast(times), out)
        m = times.size
        # Flat (m·n,) operations on the coefficients tiled once per length (the MPC
        # samples its horizon, always of one length, every step): element for element
        # the same arithmetic as sample(), with fewer and cheaper numpy calls than
        # broadcasting (m, 1) against (n,).
        omega, phase, amplitude, offset, amp_omega = self._tiles_for(m)
        arg = times.repeat(self.n)
        arg *= omega
        arg += phase
        shape = (m, self.n)
        if out is not None and (
            (out is self._out and self._out_flat[0].size == arg.size) or _flat_views_ok(out, shape)
        ):
            if out is not self._out:  # the controller passes the same buffers every step
                self._out, self._out_flat = out, (out[0].reshape(-1), out[1].reshape(-1))
            q_flat, dq_flat = self._out_flat
            np.sin(arg, out=q_flat)
            q_flat *= amplitude
            q_flat += offset
            np.cos(arg, out=dq_flat)
            dq_flat *= amp_omega
            return out
        q = np.sin(arg)
        q *= amplitude
        q += offset
        np.cos(arg, out=arg)
        arg *= amp_omega
        return _write((q.reshape(shape), arg.reshape(shape)), out)

    def native_form(self) -> tuple | None:
        """``("sine", ω, φ, amplitude, offset, amplitude·ω)`` for the native step
        (:mod:`hmpc_pin.tasks.base`); ``None`` for a subclass that samples otherwise."""
        cls = type(self)
        if cls.sample_many is not SineReference.sample_many or (
            cls.sample is not SineReference.sample
        ):
            return None
        return ("sine", self.omega, self.phase, self.amplitude, self.offset, self._amp_omega)

    def _tiles_for(self, m: int) -> tuple[FloatArray, ...]:
        tiles = self._tiles.get(m)
        if tiles is None:
            tiles = tuple(
                np.tile(c, m)
                for c in (self.omega, self.phase, self.amplitude, self.offset, self._amp_omega)
            )
            if len(self._tiles) < 8:
                self._tiles[m] = tiles
        return tiles

    def _sample_many_broadcast(self, times: FloatArray) -> Pair:
        arg = np.multiply.outer(times, self.omega)
        arg += self.phase
        q = np.sin(arg)
        q *= self.amplitude
        q += self.offset
        np.cos(arg, out=arg)
        arg *= self._amp_omega
        return q, arg

    def acceleration(self, t: float) -> np.ndarray:
        """Reference acceleration [rad/s²] at ``t``."""
        return -self.amplitude * self.omega**2 * np.sin(self.omega * t + self.phase)
