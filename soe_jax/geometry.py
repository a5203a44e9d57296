"""Rotations for every layer: quaternions to and from rotation matrices, the quaternion's sign
convention, and rotation-6d (pytorch3d's `matrix_to_rotation_6d`: the first two rows of the matrix).
Free of the simulator and at the root, so that the tasks (`envs/`, which import nothing above them),
the policy's edge (`policies/frames.py`), a robot's conventions (`data/rotations.py`) and a robot's
process (which imports nothing of `envs/`) share it. Pure JAX, or with `xp=np` numpy in float64 (a
robot's data on the host); every function broadcasts over leading dimensions.

Quaternions are Hamilton's, w the real part, with their components in the order named: MuJoCo's wxyz,
robomimic's (scipy's, ROS's) xyzw.

Each quaternion conversion is here in two formulas, equal to float precision (a test checks) but not
in the last bit (a sum in another order): `quat_wxyz_to_mat` and `mat_to_quat_wxyz`, with which every
simulated observation and scripted action was computed, and `quat_to_mat` and `mat_to_quat`, in
either order, with which relative poses and a robot's conventions were. Each path keeps its own, so no
run's numbers change; making them one changes runs in their last bits.
"""

from __future__ import annotations

import jax.numpy as jnp


def quat_to_mat(q, order: str = "xyzw", xp=jnp):
  """(..., 4) quaternion in `order` -> (..., 3, 3)."""
  q = xp.asarray(q)
  x, y, z, w = (q[..., i] for i in ((0, 1, 2, 3) if order == "xyzw" else (1, 2, 3, 0)))
  n = xp.sqrt(w * w + x * x + y * y + z * z)
  w, x, y, z = w / n, x / n, y / n, z / n
  return xp.stack(
    [
      xp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
      xp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
      xp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ],
    -2,
  )


def mat_to_quat(m, order: str = "xyzw", xp=jnp):
  """(..., 3, 3) -> (..., 4) unit quaternion in `order` with w >= 0: of the four standard formulas, the
  one whose divisor is largest (so a near-identity rotation keeps float32's precision)."""
  m = xp.asarray(m)
  m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
  m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
  m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
  # Each candidate is (x, y, z, w) times a positive factor; normalising removes it.
  candidates = xp.stack(
    [
      xp.stack([m21 - m12, m02 - m20, m10 - m01, 1 + m00 + m11 + m22], -1),
      xp.stack([1 + m00 - m11 - m22, m01 + m10, m02 + m20, m21 - m12], -1),
      xp.stack([m01 + m10, 1 - m00 + m11 - m22, m12 + m21, m02 - m20], -1),
      xp.stack([m02 + m20, m12 + m21, 1 - m00 - m11 + m22, m10 - m01], -1),
    ],
    -2,
  )
  best = xp.argmax(xp.stack([m00 + m11 + m22, m00, m11, m22], -1), -1)
  q = xp.take_along_axis(candidates, best[..., None, None], -2)[..., 0, :]
  q = q / xp.linalg.norm(q, axis=-1, keepdims=True)
  q = xp.where(q[..., 3:] < 0, -q, q)
  return q if order == "xyzw" else xp.concatenate([q[..., 3:], q[..., :3]], -1)


def quat_wxyz_to_mat(q: jnp.ndarray) -> jnp.ndarray:
  """(..., 4) wxyz unit quaternion -> (..., 3, 3) rotation matrix (the simulator's formula)."""
  q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
  w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
  return jnp.stack(
    [
      jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
      jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
      jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ],
    -2,
  )


def mat_to_quat_wxyz(m: jnp.ndarray, reference=None) -> jnp.ndarray:
  """(..., 3, 3) rotation matrix -> (..., 4) wxyz quaternion in the hemisphere of `reference` (4,)
  (q . reference >= 0; default the identity, so w >= 0), the simulator's formula. A quantity whose
  orientations stay within 180 degrees of its reference then has a quaternion that is continuous along
  every motion.

  Branch-free (Shepperd's method evaluated for all four pivots, the best one kept), so
  it vectorises and differentiates without data-dependent control flow.
  """
  m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
  tr = m00 + m11 + m22
  cands = jnp.stack(
    [
      jnp.stack([1 + tr, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
      jnp.stack(
        [m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1
      ),
      jnp.stack(
        [m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22, m[..., 1, 2] + m[..., 2, 1]], -1
      ),
      jnp.stack(
        [m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], 1 - m00 - m11 + m22], -1
      ),
    ],
    -2,
  )
  pivots = jnp.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
  best = jnp.argmax(pivots, axis=-1)
  q = jnp.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
  q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
  return same_hemisphere(q, jnp.array([1.0, 0.0, 0.0, 0.0]) if reference is None else reference)


def same_hemisphere(q: jnp.ndarray, reference) -> jnp.ndarray:
  """q (..., 4) or -q (the same rotation), whichever has a non-negative dot product with `reference`."""
  return q * jnp.where(jnp.sum(q * reference, axis=-1, keepdims=True) < 0, -1.0, 1.0)


def mat_to_rot6d(m, xp=jnp):
  """(..., 3, 3) -> (..., 6): the first two rows."""
  m = xp.asarray(m)
  return m[..., :2, :].reshape(m.shape[:-2] + (6,))


def rot6d_to_mat(d6, xp=jnp):
  """(..., 6) -> (..., 3, 3) by Gram-Schmidt on the two rows."""
  d6 = xp.asarray(d6)
  a1, a2 = d6[..., :3], d6[..., 3:]
  b1 = a1 / xp.maximum(xp.linalg.norm(a1, axis=-1, keepdims=True), 1e-8)
  a2 = a2 - xp.sum(b1 * a2, -1, keepdims=True) * b1
  b2 = a2 / xp.maximum(xp.linalg.norm(a2, axis=-1, keepdims=True), 1e-8)
  return xp.stack([b1, b2, xp.cross(b1, b2)], -2)
