"""A robot's rotation conventions to and from the policy's rotation-6d, on the host (numpy, float64), so a
dataset of axis-angle, quaternion or Euler actions fits a policy of rotation-6d ones (continuous, and
what `chunk_relative` needs) and the server replies in the robot's own convention. A convention is
{"part", "convention", "degrees"}:

  axis_angle  (3,) the rotation vector: the axis times the angle (scipy's `as_rotvec`, UR's TCP pose)
  quaternion  (4,) a unit quaternion (Hamilton's, as scipy, ROS, Eigen and MuJoCo have it), its
              components in the order `convention`: "xyzw" (scipy, ROS) or "wxyz" (MuJoCo, Eigen's
              constructor); either sign
  euler       (3,) the angles about the axes `convention` names, scipy's way: lowercase extrinsic,
              about the fixed axes ("xyz": roll, pitch, yaw), uppercase intrinsic, about the turning
              axes ("ZYX"); three different axes (Tait-Bryan) or the first again last (proper, "zxz")

`degrees`: the angles (Euler's, or axis-angle's length) in degrees, else radians. Back from
rotation-6d (Gram-Schmidt on its two rows, `soe_jax.geometry`) each convention gives scipy's canonical
values: the rotation vector of the angle in [0, pi], the quaternion with w >= 0, the Euler angles with
the first and last in [-pi, pi] and the middle in [-pi/2, pi/2] (Tait-Bryan) or [0, pi] (proper), the
last 0 at gimbal lock.
"""

from __future__ import annotations

import itertools

import numpy as np

from soe_jax import geometry

PARTS = {"axis_angle": 3, "quaternion": 4, "euler": 3}  # a robot's rotation parts -> their sizes
QUAT_ORDERS = ("xyzw", "wxyz")
EULER = tuple(
  s for a in ("xyz", "XYZ") for s in ("".join(p) for p in itertools.product(a, repeat=3)) if s[0] != s[1] != s[2]
)  # the 12 sequences, extrinsic and intrinsic
_SMALL = 1e-4  # below this angle (rad) the series of sin(t / 2) / t and its inverse are exact in float64
_LOCK = 1e-9  # gimbal lock: the middle angle's cosine (Tait-Bryan) or sine (proper) below this


def convention(part: str, quaternion: str = "xyzw", euler: str = "xyz", degrees: bool = False) -> dict:
  """The convention of a robot's rotation part `part` under the settings (ValueError naming a bad one)."""
  if part not in PARTS:
    raise ValueError(f"{part!r} is not a rotation part; known: {', '.join(PARTS)}")
  if part == "quaternion" and quaternion not in QUAT_ORDERS:
    raise ValueError(f"quaternion order {quaternion!r}; known: {', '.join(QUAT_ORDERS)}")
  if part == "euler" and euler not in EULER:
    raise ValueError(f"Euler sequence {euler!r}: three of x, y, z (extrinsic) or X, Y, Z (intrinsic), no axis twice "
                     "in a row, e.g. xyz, ZYX, zxz")  # fmt: skip
  name = {"axis_angle": "rotvec", "quaternion": quaternion, "euler": euler}[part]
  return dict(part=part, convention=name, degrees=bool(degrees) and part != "quaternion")


def _axis(k: int, angle: np.ndarray) -> np.ndarray:
  """(...,) angles -> (..., 3, 3) rotations about axis k (0 x, 1 y, 2 z)."""
  c, s = np.cos(angle), np.sin(angle)
  one, zero = np.ones_like(angle), np.zeros_like(angle)
  rows = {
    0: [[one, zero, zero], [zero, c, -s], [zero, s, c]],
    1: [[c, zero, s], [zero, one, zero], [-s, zero, c]],
    2: [[c, -s, zero], [s, c, zero], [zero, zero, one]],
  }[k]
  return np.stack([np.stack(r, -1) for r in rows], -2)


def _euler_to_matrix(angles: np.ndarray, seq: str) -> np.ndarray:
  """Intrinsic "IJK": R_I(a) R_J(b) R_K(c); extrinsic "ijk": R_k(c) R_j(b) R_i(a)."""
  axes = ["xyz".index(c) for c in seq.lower()]
  m = [_axis(k, angles[..., n]) for n, k in enumerate(axes)]
  return m[0] @ m[1] @ m[2] if seq.isupper() else m[2] @ m[1] @ m[0]


def _euler_from_matrix(m: np.ndarray, seq: str) -> np.ndarray:
  """The inverse of `_euler_to_matrix` in the module docstring's ranges. An extrinsic sequence's angles
  are the reversed sequence's intrinsic ones, reversed."""
  axes = ["xyz".index(c) for c in seq.lower()]
  i, j, k = axes if seq.isupper() else axes[::-1]
  proper = i == k
  k = 3 - i - j if proper else k
  s = 1.0 if (j - i) % 3 == 1 else -1.0  # +1 where (i, j, k) is a cyclic order of (x, y, z)
  r = lambda p, q: m[..., p, q]
  if proper:  # R_i(a) R_j(b) R_i(c): R[i, i] = cos b
    sin_b = np.hypot(r(i, j), r(i, k))
    b = np.arctan2(sin_b, r(i, i))
    a, c = np.arctan2(r(j, i), -s * r(k, i)), np.arctan2(r(i, j), s * r(i, k))
    lock = sin_b < _LOCK
  else:  # R_i(a) R_j(b) R_k(c): R[i, k] = s sin b
    cos_b = np.hypot(r(i, i), r(i, j))
    b = np.arctan2(s * r(i, k), cos_b)
    a, c = np.arctan2(-s * r(j, k), r(k, k)), np.arctan2(-s * r(i, j), r(i, i))
    lock = cos_b < _LOCK
  # At gimbal lock only a + c (or a - c) is defined: c = 0, and a from R[:, j] = R_i(a) e_j.
  a = np.where(lock, np.arctan2(s * r(k, j), r(j, j)), a)
  c = np.where(lock, 0.0, c)
  out = np.stack([a, b, c], -1)
  return out if seq.isupper() else out[..., ::-1]


def _rotvec_to_matrix(v: np.ndarray) -> np.ndarray:
  t = np.linalg.norm(v, axis=-1, keepdims=True)
  small = t < _SMALL
  k = np.where(small, 0.5 - t**2 / 48, np.sin(t / 2) / np.where(small, 1.0, t))  # sin(t / 2) / t
  return geometry.quat_to_mat(np.concatenate([v * k, np.cos(t / 2)], -1), "xyzw", xp=np)


def _rotvec_from_matrix(m: np.ndarray) -> np.ndarray:
  q = geometry.mat_to_quat(m, "xyzw", xp=np)  # w >= 0: the angle in [0, pi]
  n = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)  # sin(t / 2)
  t = 2 * np.arctan2(n, q[..., 3:])
  small = t < _SMALL
  return q[..., :3] * np.where(small, 2 + t**2 / 12, t / np.where(small, 1.0, n))  # t / sin(t / 2)


def to_matrix(x, conv: dict) -> np.ndarray:
  """(..., size) in the convention `conv` -> (..., 3, 3) rotation matrices."""
  x = np.asarray(x, np.float64)
  part, name = conv["part"], conv["convention"]
  if part == "quaternion":
    return geometry.quat_to_mat(x, name, xp=np)
  x = np.deg2rad(x) if conv.get("degrees") else x
  return _rotvec_to_matrix(x) if part == "axis_angle" else _euler_to_matrix(x, name)


def from_matrix(m, conv: dict) -> np.ndarray:
  """(..., 3, 3) rotation matrices -> (..., size) in the convention `conv`, canonical (the docstring)."""
  m = np.asarray(m, np.float64)
  part, name = conv["part"], conv["convention"]
  if part == "quaternion":
    return geometry.mat_to_quat(m, name, xp=np)
  x = _rotvec_from_matrix(m) if part == "axis_angle" else _euler_from_matrix(m, name)
  return np.rad2deg(x) if conv.get("degrees") else x


def to_6d(x, conv: dict) -> np.ndarray:
  """(..., size) in the convention `conv` -> (..., 6): the rotation matrix's first two rows."""
  return geometry.mat_to_rot6d(to_matrix(x, conv), xp=np)


def from_6d(d6, conv: dict) -> np.ndarray:
  """(..., 6) rotation-6d -> (..., size) in the convention `conv`."""
  return from_matrix(geometry.rot6d_to_mat(np.asarray(d6, np.float64), xp=np), conv)


def arm_conventions(arms: list, quaternion: str = "xyzw", euler: str = "xyz", degrees: bool = False) -> list:
  """Per arm of a robot's action layout ([[part, size], ...] each), the convention of its rotation part
  (`PARTS`) under the settings, or None for an arm with none (ValueError for two in one arm, or a size
  that is not the part's)."""
  out = []
  for k, arm in enumerate(arms):
    found = [(part, size) for part, size in arm if part in PARTS]
    if found and any(part == "rotation_6d" for part, _ in arm):
      raise ValueError(f"arm {k} has rotation_6d beside {found[0][0]}; one rotation part per arm")
    if len(found) > 1:
      raise ValueError(f"arm {k} has rotation parts {[p for p, _ in found]}; one per arm converts to rotation_6d")
    if found and found[0][1] != PARTS[found[0][0]]:
      raise ValueError(f"arm {k}'s {found[0][0]} has {found[0][1]} numbers, not {PARTS[found[0][0]]}")
    out.append(convention(found[0][0], quaternion, euler, degrees) if found else None)
  return out


def policy_arms(arms: list, conventions: list) -> list:
  """A robot's action layout -> the policy's: each converted arm's rotation part as ["rotation_6d", 6]."""
  return [[["rotation_6d", 6] if conv and part == conv["part"] else [part, size] for part, size in arm]
          for arm, conv in zip(arms, conventions)]  # fmt: skip


def convert(actions, arms: list, conventions: list, to_policy: bool) -> np.ndarray:
  """(..., A) actions laid out as `arms` (the robot's when `to_policy`, else the policy's) -> the other
  layout, each converted arm's rotation part turned into rotation-6d or back; float32."""
  actions = np.asarray(actions)
  out, at = [], 0
  for arm, conv in zip(arms, conventions):
    for part, size in arm:
      x = actions[..., at : at + size]
      if conv is not None and part == (conv["part"] if to_policy else "rotation_6d"):
        x = to_6d(x, conv) if to_policy else from_6d(x, conv)
      out.append(np.asarray(x, np.float32))
      at += size
  return np.concatenate(out, -1)
