"""openpi's msgpack-numpy frames: round trips of every kind openpi's own test sends, and clear errors
for what a stranger could send instead."""

import msgpack
import numpy as np
import pytest

from soe_jax.serve import wire

CASES = [1, 1.0, "hello", np.bool_(True), np.int64(3), [1, 2, 3], {"key": [1, 2, 3]}, np.array(1.0),
         np.array([1, 2, 3], np.int32), np.array([True, False]), np.zeros((3, 4, 5), np.float32),
         np.array([np.nan, np.inf, -np.inf]), {"arr": np.arange(3), "nested": {"arr": np.ones((2, 3), np.uint8)}}]  # fmt: skip


def _same(a, b):
  if isinstance(a, dict):
    assert a.keys() == b.keys() and all(_same(a[k], b[k]) is None for k in a)
  elif isinstance(a, np.ndarray):
    assert a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
  else:
    assert a == b and type(a) is type(b)


@pytest.mark.parametrize("data", CASES)
def test_round_trip(data):
  _same(data, wire.unpackb(wire.packb(data)))


def test_an_array_frame_is_openpis_map():
  raw = msgpack.unpackb(wire.packb(np.arange(6, dtype="<f4").reshape(2, 3)))
  assert raw == {b"__ndarray__": True, b"data": np.arange(6, dtype="<f4").tobytes(), b"dtype": "<f4", b"shape": [2, 3]}


@pytest.mark.parametrize(
  "frame, message",
  [
    ({b"__ndarray__": True, b"data": b"\0" * 5, b"dtype": "<f4", b"shape": [2]}, "needs 8 bytes, got 5"),
    ({b"__ndarray__": True, b"data": b"", b"dtype": "|O", b"shape": [0]}, "unsupported dtype object"),
    ({b"__ndarray__": True, b"data": b"", b"dtype": "nonsense", b"shape": [0]}, "not a numpy dtype"),
    ({b"__ndarray__": True, b"data": b"", b"dtype": "<f4", b"shape": "x"}, "shape must be a list"),
  ],
)
def test_what_a_stranger_could_send_is_one_clear_error(frame, message):
  with pytest.raises(wire.WireError, match=message):
    wire.unpackb(msgpack.packb(frame))
  with pytest.raises(wire.WireError, match="not a msgpack frame"):
    wire.unpackb(b"\xc1")
  with pytest.raises(wire.WireError, match="unsupported dtype complex128"):
    wire.packb(np.zeros(2, complex))
