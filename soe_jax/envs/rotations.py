"""The simulator's other rotation helpers (pure JAX): quaternion products and orders, rotations about
z, rotation vectors and the controller's orientation error. Conversions between quaternions, matrices
and rotation-6d are `soe_jax.geometry`'s. MuJoCo stores quaternions as wxyz; robomimic's observations
use xyzw. All functions broadcast over leading dimensions.
"""

from __future__ import annotations

import jax.numpy as jnp


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
