"""The simulator's rotation helpers against scipy's `Rotation` (an independent implementation), on
random rotations and half-turns (the conversions are `soe_jax.geometry`'s: `tests/test_geometry.py`)."""

import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

from soe_jax import geometry
from soe_jax.envs import rotations


def _rotations(n=256, seed=0):
  r = Rotation.random(n, random_state=seed)
  half_turns = Rotation.from_rotvec(np.pi * np.eye(3))  # trace -1: the w pivot vanishes
  return Rotation.concatenate([r, half_turns])


def _wxyz(r: Rotation) -> np.ndarray:
  return np.roll(r.as_quat(), 1, axis=-1)  # scipy's quaternions are xyzw


def test_products_orders_rotation_vectors_and_yaws_match_scipy():
  a, b = _rotations(seed=1), _rotations(seed=2)
  product = rotations.quat_mul_wxyz(jnp.asarray(_wxyz(a), jnp.float32), jnp.asarray(_wxyz(b), jnp.float32))
  np.testing.assert_allclose(geometry.quat_wxyz_to_mat(product), (a * b).as_matrix(), atol=1e-5)
  conj = rotations.quat_conj_wxyz(jnp.asarray(_wxyz(a), jnp.float32))
  np.testing.assert_allclose(geometry.quat_wxyz_to_mat(conj), a.inv().as_matrix(), atol=1e-5)
  v = a.as_rotvec()
  np.testing.assert_allclose(rotations.axis_angle_to_mat(jnp.asarray(v, jnp.float32)), a.as_matrix(), atol=1e-5)
  np.testing.assert_allclose(rotations.wxyz_to_xyzw(jnp.asarray(_wxyz(a))), a.as_quat(), atol=1e-7)
  yaw = np.linspace(-3, 3, 7)
  np.testing.assert_allclose(
    rotations.rotz(jnp.asarray(yaw)), Rotation.from_euler("z", yaw[:, None]).as_matrix(), atol=1e-6
  )
  want = _wxyz(Rotation.from_euler("z", yaw[:, None]))
  np.testing.assert_allclose(rotations.yaw_quat_wxyz(jnp.asarray(yaw)), want * np.sign(want[:, :1]), atol=1e-6)
