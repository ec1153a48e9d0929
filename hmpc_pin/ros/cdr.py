"""``sensor_msgs/JointState`` and ``std_msgs/Float64MultiArray`` read from their
serialized form (CDR), without rclpy's message conversion.

A subscription created with ``raw=True`` hands over each message as the bytes the
middleware received: the encapsulation header (2 bytes naming the encoding, 2 of
options) and the message in the OMG's Common Data Representation (XCDR version 1,
plain CDR: every primitive aligned to its size from the end of the header; a string
is a ``uint32`` length counting its terminating NUL, then its bytes; a sequence a
``uint32`` count, then its elements). Converting a ``JointState`` into a Python message
builds a string per joint name and an array per field (tens of µs per state, taken on
the controller's cycle); here the names are decoded only when their bytes change, and
the positions and velocities are read as float64 views of the buffer (a few µs); a
``Float64MultiArray`` (the effort command) is its ``data`` viewed alike.

Only little-endian plain CDR (encapsulation ``CDR_LE``, what ROS 2's middlewares send
on every little-endian machine) is read here; :class:`JointStateReader` returns
``None`` for any other encoding, and the caller falls back to rclpy's deserialisation.
"""

from __future__ import annotations

import struct

import numpy as np

__all__ = ["CDR_LE", "JointStateReader", "RawJointState", "read_float64_array"]

#: The encapsulation header of little-endian plain CDR (``CDR_LE``).
CDR_LE = b"\x00\x01"

_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<iI")


class RawJointState:
    """The parts of a ``JointState`` the controller reads, as ``msg.name``,
    ``msg.position``, ``msg.velocity`` and ``msg.header.stamp`` are read from a message.

    Attributes:
        name: The joint names (a list shared by the messages that carry the same names:
            do not modify).
        position, velocity: [rad, rad/s] read-only float64 views of the message's bytes.
        header: ``header.stamp.sec`` and ``header.stamp.nanosec``.
    """

    __slots__ = ("header", "name", "position", "velocity")

    def __init__(self, name: list[str], position: np.ndarray, velocity: np.ndarray, sec, nsec):
        self.name = name
        self.position = position
        self.velocity = velocity
        self.header = _Header(sec, nsec)


class _Stamp:
    __slots__ = ("nanosec", "sec")

    def __init__(self, sec: int, nanosec: int):
        self.sec, self.nanosec = sec, nanosec


class _Header:
    __slots__ = ("stamp",)

    def __init__(self, sec: int, nanosec: int):
        self.stamp = _Stamp(sec, nanosec)


class JointStateReader:
    """Decodes serialized ``JointState`` messages (module doc); remembers the last names.

    Attributes:
        decoded_names: How many times the names were decoded (their bytes changed).
    """

    def __init__(self) -> None:
        # the names' sequence last decoded: its count and strings (offset from its start,
        # bytes; the padding between them is not compared: it may hold anything) and size
        self._pieces: list[tuple[int, bytes]] = []
        self._names_end = 0
        self._names: list[str] = []
        self.decoded_names = 0

    def __call__(self, data: bytes) -> RawJointState | None:
        """The message in ``data`` (encapsulation header included), or ``None`` if it is
        not little-endian plain CDR or ends before the message does (the caller
        deserialises it with rclpy, which reports what is wrong)."""
        if data[:2] != CDR_LE:
            return None
        try:
            return self._read(data)
        except (struct.error, UnicodeDecodeError):  # a length past the end, not UTF-8
            return None

    def _same_names(self, view: memoryview, start: int) -> bool:
        """Whether the names at ``start`` are those last decoded (the same count and
        strings: a sequence's bytes delimit it)."""
        return all(view[start + at : start + at + len(p)] == p for at, p in self._pieces)

    def _read(self, data: bytes) -> RawJointState | None:
        view = memoryview(data)[4:]  # alignment counts from after the header
        sec, nsec = _STAMP.unpack_from(view, 0)
        pos = _skip_string(view, 8)  # header.frame_id
        start = _align(pos, 4)
        if self._names_end and self._same_names(view, start):
            pos = start + self._names_end
        else:
            (count,) = _U32.unpack_from(view, start)
            pos = start + 4
            pieces = [(0, bytes(view[start:pos]))]
            for _ in range(count):
                at = _align(pos, 4)
                pos = _skip_string(view, at)
                pieces.append((at - start, bytes(view[at:pos])))
            if pos > len(view):
                return None
            self._names = _read_strings(view, start)
            self._pieces, self._names_end = pieces, pos - start
            self.decoded_names += 1
        position, pos = _read_doubles(view, pos)
        velocity, _ = _read_doubles(view, pos)
        if position is None or velocity is None:
            return None
        return RawJointState(self._names, position, velocity, sec, nsec)


def read_float64_array(data: bytes) -> np.ndarray | None:
    """The ``data`` field of the ``Float64MultiArray`` serialized in ``data``
    (encapsulation header included; its layout skipped) as a read-only float64 view, or
    ``None`` if it is not little-endian plain CDR or ends before the message does."""
    if data[:2] != CDR_LE:
        return None
    view = memoryview(data)[4:]
    try:
        (dims,) = _U32.unpack_from(view, 0)
        pos = 4
        for _ in range(dims):  # MultiArrayDimension: label, size, stride
            pos = _skip_string(view, _align(pos, 4))
            pos = _align(pos, 4) + 8
        pos = _align(pos, 4) + 4  # layout.data_offset
        return _read_doubles(view, pos)[0]
    except struct.error:
        return None


def _align(pos: int, size: int) -> int:
    return (pos + size - 1) // size * size


def _skip_string(view: memoryview, pos: int) -> int:
    """The position after the string at ``pos`` (aligned)."""
    (length,) = _U32.unpack_from(view, pos)
    return pos + 4 + length


def _read_strings(view: memoryview, pos: int) -> list[str]:
    """The ``sequence<string>`` at ``pos`` (aligned)."""
    (count,) = _U32.unpack_from(view, pos)
    pos += 4
    out = []
    for _ in range(count):
        pos = _align(pos, 4)
        (length,) = _U32.unpack_from(view, pos)
        out.append(bytes(view[pos + 4 : pos + 3 + length]).decode())
        pos += 4 + length
    return out


def _read_doubles(view: memoryview, pos: int) -> tuple[np.ndarray | None, int]:
    """The ``sequence<float64>`` at ``pos`` (``None``: past the end) and the position
    after it."""
    pos = _align(pos, 4)
    (count,) = _U32.unpack_from(view, pos)
    pos = _align(pos + 4, 8) if count else pos + 4
    end = pos + 8 * count
    if end > len(view):
        return None, end
    return np.frombuffer(view, dtype="<f8", count=count, offset=pos), end
