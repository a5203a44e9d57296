"""Rotations for every layer (`soe_jax/geometry.py`) against scipy's `Rotation` (an independent
implementation), on random rotations and the half-turns where conversions branch: both formulas of each
quaternion conversion, in both component orders, in JAX and in numpy's float64, agree with scipy and
with each other to float precision; rotation-6d round-trips."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from soe_jax import geometry


def _rotations(n=256, seed=0):
  r = Rotation.random(n, random_state=seed)
  half_turns = Rotation.from_rotvec(np.pi * np.eye(3))  # trace -1: the w pivot vanishes
  return Rotation.concatenate([r, half_turns])


def _in(order: str, xyzw: np.ndarray) -> np.ndarray:
  return xyzw if order == "xyzw" else np.roll(xyzw, 1, axis=-1)  # scipy's quaternions are xyzw


def _same_rotation(got, want):
  np.testing.assert_allclose(np.abs(np.sum(np.asarray(got) * want, -1)), 1.0, atol=1e-5)


def test_the_simulators_formulas_match_scipy():
  r = _rotations()
  q, m = _in("wxyz", r.as_quat()), r.as_matrix()
  np.testing.assert_allclose(geometry.quat_wxyz_to_mat(jnp.asarray(q, jnp.float32)), m, atol=1e-5)
  got = np.asarray(geometry.mat_to_quat_wxyz(jnp.asarray(m, jnp.float32)))
  _same_rotation(got, q)
  assert np.all(got[:, 0] >= -1e-7)  # the identity's hemisphere: w >= 0
  flipped = np.asarray(geometry.mat_to_quat_wxyz(jnp.asarray(m, jnp.float32), -jnp.asarray(got[0])))
  assert np.sum(flipped[0] * got[0]) < 0  # in another reference's hemisphere: the other sign


@pytest.mark.parametrize("order", ["xyzw", "wxyz"])
@pytest.mark.parametrize("xp", [jnp, np], ids=["jax", "numpy"])
def test_the_formulas_of_either_order_match_scipy(order, xp):
  r = _rotations(seed=1)
  q, m = _in(order, r.as_quat()), r.as_matrix()
  atol = 1e-5 if xp is jnp else 1e-12
  np.testing.assert_allclose(geometry.quat_to_mat(xp.asarray(q), order, xp=xp), m, atol=atol)
  got = np.asarray(geometry.mat_to_quat(xp.asarray(m), order, xp=xp))
  _same_rotation(got, q)
  assert np.all(got[:, order.index("w")] >= -1e-7)


def test_the_two_formulas_agree_and_rot6d_round_trips():
  m = _rotations(seed=2).as_matrix().astype(np.float32)
  wxyz = geometry.mat_to_quat_wxyz(jnp.asarray(m))
  np.testing.assert_allclose(geometry.mat_to_quat(m, "wxyz"), wxyz, atol=1e-6)
  np.testing.assert_allclose(geometry.quat_to_mat(wxyz, "wxyz"), geometry.quat_wxyz_to_mat(wxyz), atol=1e-6)
  d6 = geometry.mat_to_rot6d(m)
  np.testing.assert_allclose(d6, m[:, :2, :].reshape(-1, 6), atol=0)
  np.testing.assert_allclose(geometry.rot6d_to_mat(d6), m, atol=1e-6)
  np.testing.assert_allclose(geometry.rot6d_to_mat(2.0 * d6, xp=np), m, atol=1e-6)  # (unnormalised rows too)
