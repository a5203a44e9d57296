"""Relative poses at the policy's edge: to_relative and to_absolute invert each other on random poses
(the base being the latest observation's pose), and the latest observed pose becomes the origin."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax import geometry
from soe_jax.data.spec import PolicySpec
from soe_jax.envs import registry
from soe_jax.policies import frames


def _random_rotations(key, n):
  q = jax.random.normal(key, (n, 4))
  return q / jnp.linalg.norm(q, axis=-1, keepdims=True)  # xyzw


def _history_and_chunk(spec, key, b=16, to=2, t=16):
  layout = frames.PoseLayout.from_spec(spec)
  keys = jax.random.split(key, 6)
  obs = jax.random.normal(keys[0], (b, to, spec.obs_dim))
  for k in range(len(layout.obs_position)):
    p, q = layout.obs_position[k], layout.obs_quat[k]
    obs = obs.at[..., p : p + 3].set(jax.random.uniform(keys[1], (b, to, 3), minval=-0.5, maxval=1.0))
    obs = obs.at[..., q : q + 4].set(_random_rotations(keys[2], b * to).reshape(b, to, 4))
  actions = jax.random.uniform(keys[3], (b, t, spec.action_dim), minval=-1.0, maxval=1.0)
  for k in range(len(layout.action_rot6d)):
    r = layout.action_rot6d[k]
    mats = geometry.quat_to_mat(_random_rotations(jax.random.fold_in(keys[4], k), b * t)).reshape(b, t, 3, 3)
    actions = actions.at[..., r : r + 6].set(geometry.mat_to_rot6d(mats))
  return layout, obs, actions


@pytest.mark.slow
def test_relative_and_absolute_invert_each_other_on_random_poses_of_two_arms():
  spec = PolicySpec.from_dict(registry.task_spec("transport", "absolute"))
  with jax.enable_x64(True):  # the conversions' own error, apart from float32's rounding
    layout, obs, actions = _history_and_chunk(spec, jax.random.key(0))
    obs, actions = obs.astype(jnp.float64), actions.astype(jnp.float64)
    np.testing.assert_allclose(layout.to_absolute(obs, layout.to_relative(obs, actions)), actions, atol=1e-6)
  layout, obs, actions = _history_and_chunk(spec, jax.random.key(0))
  rel = layout.to_relative(obs, actions)
  np.testing.assert_allclose(layout.to_absolute(obs, rel), actions, atol=5e-6)  # in the policy's float32
  gripper = [9, 19]
  np.testing.assert_array_equal(rel[..., gripper], actions[..., gripper])  # the gripper stays absolute
  # The base is the latest observation's pose: a chunk at that pose is the origin and the identity.
  for k in range(2):
    p, q, a, r = layout.obs_position[k], layout.obs_quat[k], layout.action_position[k], layout.action_rot6d[k]
    at_base = actions.at[:, :, a : a + 3].set(obs[:, -1:, p : p + 3])
    at_base = at_base.at[:, :, r : r + 6].set(geometry.mat_to_rot6d(geometry.quat_to_mat(obs[:, -1:, q : q + 4])))
    rel = layout.to_relative(obs, at_base)
    np.testing.assert_allclose(rel[..., a : a + 3], 0.0, atol=1e-6)
    np.testing.assert_allclose(
      rel[..., r : r + 6], jnp.broadcast_to(jnp.array([1.0, 0, 0, 0, 1, 0]), rel[..., r : r + 6].shape), atol=1e-6
    )
    seen = layout.observe(obs)
    np.testing.assert_allclose(seen[:, -1, p : p + 3], 0.0, atol=1e-6)
    np.testing.assert_allclose(seen[:, -1, q : q + 4], jnp.broadcast_to(jnp.array([0.0, 0, 0, 1]), (16, 4)), atol=1e-6)


def test_a_spec_without_poses_is_refused_for_relative_actions():
  spec = PolicySpec.from_dict(dict(registry.task_spec("lift", "absolute"), poses=None))
  import pytest

  with pytest.raises(ValueError, match="needs the spec's `poses`"):
    frames.PoseLayout.from_spec(spec)
