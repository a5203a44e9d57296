"""Rotation conventions used by the tasks and the policy's actions (pure JAX).

MuJoCo stores quaternions as wxyz; robomimic's observations use xyzw. Rotation-6d is
pytorch3d's `matrix_to_rotation_6d`: the first two *rows* of the rotation matrix.
All functions broadcast over leading dimensions.
"""

from __future__ import annotations

import jax.numpy as jnp


def quat_wxyz_to_mat(q: jnp.ndarray) -> jnp.ndarray:
  """(..., 4) wxyz unit quaternion -> (..., 3, 3) rotation matrix."""
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
  (q . reference >= 0; default the identity, so w >= 0). A quantity whose orientations stay within
  180 degrees of its reference then has a quaternion that is continuous along every motion.

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


def quat_conj_wxyz(q: jnp.ndarray) -> jnp.ndarray:
  return q * jnp.array([1.0, -1.0, -1.0, -1.0])


def quat_mul_wxyz(a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
  """Hamilton product a * b of wxyz quaternions (the rotation R(a) R(b))."""
  aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
  bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
  return jnp.stack(
    [
      aw * bw - ax * bx - ay * by - az * bz,
      aw * bx + ax * bw + ay * bz - az * by,
      aw * by - ax * bz + ay * bw + az * bx,
      aw * bz + ax * by - ay * bx + az * bw,
    ],
    -1,
  )


def wxyz_to_xyzw(q: jnp.ndarray) -> jnp.ndarray:
  return jnp.concatenate([q[..., 1:], q[..., :1]], -1)


def yaw_quat_wxyz(yaw: jnp.ndarray) -> jnp.ndarray:
  """Rotation about world z by `yaw` radians, as a wxyz quaternion."""
  h = 0.5 * yaw
  z = jnp.zeros_like(h)
  return jnp.stack([jnp.cos(h), z, z, jnp.sin(h)], -1)


def rotz(yaw: jnp.ndarray) -> jnp.ndarray:
  c, s = jnp.cos(yaw), jnp.sin(yaw)
  z, o = jnp.zeros_like(c), jnp.ones_like(c)
  return jnp.stack([jnp.stack([c, -s, z], -1), jnp.stack([s, c, z], -1), jnp.stack([z, z, o], -1)], -2)


def mat_to_rot6d(m: jnp.ndarray) -> jnp.ndarray:
  """(..., 3, 3) -> (..., 6): the first two rows, flattened (pytorch3d convention)."""
  return m[..., :2, :].reshape(m.shape[:-2] + (6,))


def rot6d_to_mat(d6: jnp.ndarray) -> jnp.ndarray:
  """(..., 6) -> (..., 3, 3) by Gram-Schmidt on the two rows (pytorch3d convention)."""
  a1, a2 = d6[..., :3], d6[..., 3:]
  b1 = a1 / jnp.maximum(jnp.linalg.norm(a1, axis=-1, keepdims=True), 1e-8)
  a2 = a2 - jnp.sum(b1 * a2, -1, keepdims=True) * b1
  b2 = a2 / jnp.maximum(jnp.linalg.norm(a2, axis=-1, keepdims=True), 1e-8)
  b3 = jnp.cross(b1, b2)
  return jnp.stack([b1, b2, b3], -2)


def axis_angle_to_mat(v: jnp.ndarray) -> jnp.ndarray:
  """(..., 3) rotation vector -> (..., 3, 3) (Rodrigues), safe at zero."""
  theta2 = jnp.sum(v * v, -1)[..., None, None]
  theta = jnp.sqrt(jnp.maximum(theta2, 1e-24))
  small = theta2 < 1e-12
  a = jnp.where(small, 1.0 - theta2 / 6.0, jnp.sin(theta) / theta)
  b = jnp.where(small, 0.5 - theta2 / 24.0, (1.0 - jnp.cos(theta)) / jnp.maximum(theta2, 1e-24))
  x, y, z = v[..., 0], v[..., 1], v[..., 2]
  zero = jnp.zeros_like(x)
  k = jnp.stack([jnp.stack([zero, -z, y], -1), jnp.stack([z, zero, -x], -1), jnp.stack([-y, x, zero], -1)], -2)
  eye = jnp.broadcast_to(jnp.eye(3, dtype=v.dtype), k.shape)
  return eye + a * k + b * (k @ k)


def rotation_error(r: jnp.ndarray, r_goal: jnp.ndarray) -> jnp.ndarray:
  """Orientation error as a world-frame rotation vector taking `r` to `r_goal` (small-angle exact).

  This is robosuite's OSC error, e = 1/2 * sum_i r[:, i] x r_goal[:, i].
  """
  return 0.5 * jnp.sum(jnp.cross(jnp.swapaxes(r, -1, -2), jnp.swapaxes(r_goal, -1, -2)), axis=-2)
