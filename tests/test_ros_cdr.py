"""The serialized-message readers (hmpc_pin/ros/cdr.py) against rclpy's own serialisation,
and the CDR layout against an encoder written here from the specification; the
middleware defaults (hmpc_pin/ros/middleware.py). No DDS: serialisation only."""

from __future__ import annotations

import struct

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from hmpc_pin.ros.cdr import JointStateReader, read_float64_array
from hmpc_pin.ros.interface import _deserialize
from hmpc_pin.ros.middleware import MIDDLEWARE_DEFAULTS, apply_middleware_defaults


def _joint_state(names, position, velocity, frame="", sec=0, nsec=0, effort=()):
    msg = JointState()
    msg.name = list(names)
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nsec
    msg.position = [float(x) for x in position]
    msg.velocity = [float(x) for x in velocity]
    msg.effort = [float(x) for x in effort]
    return msg


class _Cdr:
    """Plain CDR (XCDR1) written from the specification: each primitive aligned to its
    size from the end of the 4-byte encapsulation header; a string is its length with
    the NUL, its bytes and the NUL; a sequence its count, then its elements."""

    def __init__(self, endian: str):
        self.e = endian
        self.body = bytearray()
        self.padding: list[int] = []  # offsets of the padding bytes (any value)

    def _pad(self, size: int) -> None:
        n = -len(self.body) % size
        self.padding += range(4 + len(self.body), 4 + len(self.body) + n)
        self.body += b"\0" * n

    def u32(self, x: int) -> None:
        self._pad(4)
        self.body += struct.pack(self.e + "I", x)

    def i32(self, x: int) -> None:
        self._pad(4)
        self.body += struct.pack(self.e + "i", x)

    def string(self, s: str) -> None:
        raw = s.encode() + b"\0"
        self.u32(len(raw))
        self.body += raw

    def doubles(self, xs) -> None:
        self.u32(len(xs))
        if len(xs):
            self._pad(8)
            self.body += struct.pack(self.e + f"{len(xs)}d", *xs)

    def bytes(self) -> bytes:
        head = b"\x00\x01\x00\x00" if self.e == "<" else b"\x00\x00\x00\x00"
        return head + bytes(self.body)


def _encode_joint_state(names, position, velocity, effort, frame, sec, nsec, endian="<", w=None):
    w = _Cdr(endian) if w is None else w
    w.i32(sec)
    w.u32(nsec)
    w.string(frame)
    w.u32(len(names))
    for name in names:
        w.string(name)
    for xs in (position, velocity, effort):
        w.doubles(xs)
    return w.bytes()


# every alignment: frame ids and names of each length mod 8, empty sequences in each place
CASES = [
    (["panda_joint1", "panda_joint2"], 2, 2, 2, "", 1_700_000_123, 456_789_012),
    (["a"], 1, 1, 0, "b", 5, 7),
    (["ab", "c"], 2, 0, 3, "xyz12", 0, 0),
    (["ab"], 0, 1, 1, "f", 1, 2),
    (["ab"], 0, 0, 0, "", 3, 4),
    ([], 0, 0, 0, "base_link", 9, 10),
    (
        ["a", "bb", "ccc", "dddd", "eeeee", "ffffff", "ggggggg"],
        7,
        7,
        7,
        "1234567",
        2**31 - 1,
        999_999_999,
    ),
]


@pytest.mark.parametrize("names, n_p, n_v, n_e, frame, sec, nsec", CASES)
def test_a_joint_state_reads_as_rclpy_deserialises_it(names, n_p, n_v, n_e, frame, sec, nsec):
    rng = np.random.default_rng(len(names) + 10 * n_p + 100 * n_v)
    p, v, e = rng.standard_normal(n_p), rng.standard_normal(n_v), rng.standard_normal(n_e)
    data = serialize_message(_joint_state(names, p, v, frame, sec, nsec, e))
    # the layout as the specification writes it (the padding bytes are left unset)
    w = _Cdr("<")
    spec = _encode_joint_state(names, p, v, e, frame, sec, nsec, w=w)
    # (rclpy's buffer may end with a few bytes past the message: unread)
    assert 0 <= len(data) - len(spec) <= 8
    masked = bytearray(data[: len(spec)])
    for i in w.padding:
        masked[i] = 0
    assert bytes(masked) == spec
    ref = deserialize_message(data, JointState)
    got = JointStateReader()(data)
    assert got is not None
    assert got.name == list(ref.name) == names
    np.testing.assert_array_equal(got.position, np.asarray(ref.position))
    np.testing.assert_array_equal(got.velocity, np.asarray(ref.velocity))
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (sec, nsec)


def test_names_are_decoded_once_while_their_bytes_stay_the_same():
    read = JointStateReader()
    names = ["j1", "j2", "j3"]
    for k in range(5):  # frame ids of changing length move the names: still recognised
        msg = _joint_state(names, [k, 1, 2], [3, 4, k], frame="f" * k, sec=k)
        got = read(serialize_message(msg))
        assert got.name == names and got.position[0] == k and got.velocity[2] == k
    assert read.decoded_names == 1
    got = read(serialize_message(_joint_state(["j1", "j2", "j4"], [0, 0, 0], [0, 0, 0])))
    assert got.name == ["j1", "j2", "j4"] and read.decoded_names == 2
    # same total length, other names: decoded again
    got = read(serialize_message(_joint_state(["j1", "j2", "j3"], [0, 0, 0], [0, 0, 0])))
    assert got.name == names and read.decoded_names == 3


def test_big_endian_or_truncated_bytes_fall_back_to_rclpy():
    names, p, v = ["a", "bc"], [0.5, -1.5], [2.0, 3.25]
    big = _encode_joint_state(names, p, v, [], "base", 12, 34, endian=">")
    assert JointStateReader()(big) is None
    ref = _deserialize(big, JointState)  # what the interface takes instead
    assert list(ref.name) == names and list(ref.position) == p and list(ref.velocity) == v
    data = serialize_message(_joint_state(names, p, v))
    end = len(_encode_joint_state(names, p, v, [], "", 0, 0))  # then: effort's count (4 B)
    for cut in (6, 20, 30, end - 4 - 8, end - 5):  # in the names, position, velocity
        assert JointStateReader()(data[:cut]) is None, cut
    assert JointStateReader()(data[: end - 4]) is not None  # (effort is not read)
    assert read_float64_array(b"\x00\x00\x00\x00" + bytes(12)) is None


@pytest.mark.parametrize("dims", [[], [("joints", 7, 7)], [("", 2, 6), ("xyz", 3, 3)]])
@pytest.mark.parametrize("n", [0, 1, 7])
def test_a_float64_multiarray_reads_as_rclpy_deserialises_it(dims, n):
    msg = Float64MultiArray()
    for label, size, stride in dims:
        msg.layout.dim.append(MultiArrayDimension(label=label, size=size, stride=stride))
    msg.layout.data_offset = 3
    msg.data = [float(x) for x in np.linspace(-1.0, 2.0, n)]
    data = serialize_message(msg)
    got = read_float64_array(data)
    np.testing.assert_array_equal(
        got, np.asarray(deserialize_message(data, Float64MultiArray).data)
    )
    assert got.shape == (n,)
    assert read_float64_array(data[:-1]) is None if n else True


def test_middleware_defaults_fill_only_what_the_user_left_unset():
    key, value = "RMW_FASTRTPS_PUBLICATION_MODE", "SYNCHRONOUS"
    assert MIDDLEWARE_DEFAULTS[key] == value
    env: dict[str, str] = {}
    assert apply_middleware_defaults(env) == {key: value} and env[key] == value
    env = {key: ""}  # an empty variable is unset for the middleware too
    assert apply_middleware_defaults(env) == {key: value} and env[key] == value
    env = {key: "ASYNCHRONOUS"}  # the user's choice wins
    assert apply_middleware_defaults(env) == {} and env == {key: "ASYNCHRONOUS"}
