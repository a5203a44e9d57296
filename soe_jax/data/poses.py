"""Pose conversions for data and the policy's edge, free of the simulator (pure JAX, numpy in, numpy or
JAX out): quaternions (xyzw or wxyz) and rotation-6d (pytorch3d's `matrix_to_rotation_6d`: the first
two rows of the rotation matrix) to and from rotation matrices. `envs.rotations` has the simulator's
own; a test checks the two agree.
"""

from __future__ import annotations

import jax.numpy as jnp


def quat_to_mat(q, order: str = "xyzw"):
  """(..., 4) quaternion in `order` -> (..., 3, 3)."""
  q = jnp.asarray(q)
  x, y, z, w = (q[..., i] for i in ((0, 1, 2, 3) if order == "xyzw" else (1, 2, 3, 0)))
  n = jnp.sqrt(w * w + x * x + y * y + z * z)
  w, x, y, z = w / n, x / n, y / n, z / n
  return jnp.stack(
    [
      jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
      jnp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
      jnp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ],
    -2,
  )


def mat_to_quat(m, order: str = "xyzw"):
  """(..., 3, 3) -> (..., 4) unit quaternion in `order` with w >= 0: of the four standard formulas, the
  one whose divisor is largest (so a near-identity rotation keeps float32's precision)."""
  m = jnp.asarray(m)
  m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
  m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
  m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
  # Each candidate is (x, y, z, w) times a positive factor; normalising removes it.
  candidates = jnp.stack(
    [
      jnp.stack([m21 - m12, m02 - m20, m10 - m01, 1 + m00 + m11 + m22], -1),
      jnp.stack([1 + m00 - m11 - m22, m01 + m10, m02 + m20, m21 - m12], -1),
      jnp.stack([m01 + m10, 1 - m00 + m11 - m22, m12 + m21, m02 - m20], -1),
      jnp.stack([m02 + m20, m12 + m21, 1 - m00 - m11 + m22, m10 - m01], -1),
    ],
    -2,
  )
  best = jnp.argmax(jnp.stack([m00 + m11 + m22, m00, m11, m22], -1), -1)
  q = jnp.take_along_axis(candidates, best[..., None, None], -2)[..., 0, :]
  q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
  q = jnp.where(q[..., 3:] < 0, -q, q)
  return q if order == "xyzw" else jnp.concatenate([q[..., 3:], q[..., :3]], -1)


def mat_to_rot6d(m):
  """(..., 3, 3) -> (..., 6): the first two rows."""
  m = jnp.asarray(m)
  return m[..., :2, :].reshape(m.shape[:-2] + (6,))


def rot6d_to_mat(d6):
  """(..., 6) -> (..., 3, 3) by Gram-Schmidt on the two rows."""
  d6 = jnp.asarray(d6)
  a1, a2 = d6[..., :3], d6[..., 3:]
  b1 = a1 / jnp.maximum(jnp.linalg.norm(a1, axis=-1, keepdims=True), 1e-8)
  a2 = a2 - jnp.sum(b1 * a2, -1, keepdims=True) * b1
  b2 = a2 / jnp.maximum(jnp.linalg.norm(a2, axis=-1, keepdims=True), 1e-8)
  return jnp.stack([b1, b2, jnp.cross(b1, b2)], -2)
