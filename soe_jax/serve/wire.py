"""openpi's wire format: msgpack, with numpy arrays as maps (`openpi_client/msgpack_numpy.py`).

  ndarray        {b"__ndarray__": True, b"data": raw bytes, b"dtype": dtype.str, b"shape": [...]}
  numpy scalar   {b"__npgeneric__": True, b"data": item, b"dtype": dtype.str}

Object, void and complex dtypes are refused both ways (openpi's rule: nothing that would need pickle).
Decoding checks what a stranger could get wrong (a dtype that is not one, data of the wrong length) and
raises `WireError` with one line instead of numpy's error.
"""

from __future__ import annotations

import math

import msgpack
import numpy as np

REFUSED_KINDS = ("V", "O", "c")


class WireError(ValueError):
  """A frame that is not openpi's msgpack-numpy."""


def _pack(obj):
  if isinstance(obj, (np.ndarray, np.generic)) and obj.dtype.kind in REFUSED_KINDS:
    raise WireError(f"unsupported dtype {obj.dtype} (object, void and complex arrays are not sent)")
  if isinstance(obj, np.ndarray):
    obj = obj if obj.flags.c_contiguous else obj.copy(order="C")  # (ascontiguousarray makes 0-d 1-d)
    return {b"__ndarray__": True, b"data": obj.tobytes(), b"dtype": obj.dtype.str, b"shape": list(obj.shape)}
  if isinstance(obj, np.generic):
    return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
  return obj


def _dtype(name) -> np.dtype:
  try:
    dtype = np.dtype(name)
  except (TypeError, ValueError):
    raise WireError(f"not a numpy dtype: {name!r}") from None
  if dtype.kind in REFUSED_KINDS:
    raise WireError(f"unsupported dtype {dtype} (object, void and complex arrays are refused)")
  return dtype


def _unpack(obj: dict):
  if b"__ndarray__" in obj:
    dtype, shape, data = _dtype(obj.get(b"dtype")), obj.get(b"shape"), obj.get(b"data")
    if not isinstance(shape, (list, tuple)) or not all(isinstance(n, int) and n >= 0 for n in shape):
      raise WireError(f"an array's shape must be a list of sizes, got {shape!r}")
    if not isinstance(data, bytes) or len(data) != math.prod(shape) * dtype.itemsize:
      size = len(data) if isinstance(data, bytes) else type(data).__name__
      raise WireError(
        f"an array of shape {list(shape)} and dtype {dtype} needs {math.prod(shape) * dtype.itemsize} bytes, got {size}"
      )
    return np.frombuffer(data, dtype).reshape(tuple(shape))
  if b"__npgeneric__" in obj:
    return _dtype(obj.get(b"dtype")).type(obj.get(b"data"))
  return obj


def packb(obj) -> bytes:
  return msgpack.packb(obj, default=_pack)


def unpackb(data: bytes):
  try:
    return msgpack.unpackb(data, object_hook=_unpack)
  except WireError:
    raise
  except Exception as e:  # msgpack's own errors: truncated, extra data, bad types
    raise WireError(f"not a msgpack frame: {type(e).__name__}: {e}") from None
