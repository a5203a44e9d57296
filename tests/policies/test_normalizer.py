"""Per-dimension limits with a margin and span floors; identity for rotation-6d and gripper; no clip of
observations, and the out-of-range fraction."""

import jax.numpy as jnp
import numpy as np

from soe_jax.envs import observations
from soe_jax.policies import normalizer


def _fit(min_span=None):
  rng = np.random.default_rng(0)
  obs = rng.uniform([0, -5, 2], [1, 5, 2], size=(500, 3)).astype(np.float32)  # third dim constant
  obs[:2, :2] = [[0, -5], [1, 5]]  # the ranges exactly [0, 1] and [-5, 5]
  actions = rng.uniform(-0.5, 0.5, size=(500, 10)).astype(np.float32)
  return obs, actions, normalizer.fit(obs, actions, margin=0.1, obs_min_span=min_span)


def test_limits_with_margin_and_identity_action_dims():
  obs, actions, norm = _fit()
  y = np.asarray(norm.normalize_obs(obs))
  # The data's range maps to [-1/1.2, 1/1.2]: 10% margin on each side.
  np.testing.assert_allclose(y[:, :2].max(0), 1 / 1.2, atol=1e-6)
  np.testing.assert_allclose(y[:, :2].min(0), -1 / 1.2, atol=1e-6)
  np.testing.assert_allclose(y[:, 2], 0.0, atol=1e-6)  # a constant dim without a floor is only shifted
  a = np.asarray(norm.normalize_actions(actions))
  np.testing.assert_array_equal(a[:, 3:], actions[:, 3:])  # rotation-6d and gripper as they are
  np.testing.assert_allclose(np.asarray(norm.unnormalize_actions(a)), actions, atol=1e-5)


def test_two_robots_positions_are_normalised_in_each_block():
  """Transport's actions are two blocks of 10: each block's position is scaled, the rest kept."""
  rng = np.random.default_rng(1)
  actions = rng.uniform(-0.5, 0.5, size=(500, 20))
  actions[:, 10:13] = rng.uniform(0.8, 1.2, size=(500, 3))  # robot1's positions, beyond [-1, 1] raw
  norm = normalizer.fit(np.zeros((500, 2)), actions, margin=0.1, num_robots=2)
  a = np.asarray(norm.normalize_actions(actions))
  for block in (slice(0, 3), slice(10, 13)):
    np.testing.assert_allclose(np.abs(a[:, block]).max(0), 1 / 1.2, rtol=1e-3)
  kept = np.r_[3:10, 13:20]
  np.testing.assert_allclose(a[:, kept], actions[:, kept], atol=1e-6)


def test_an_observation_far_outside_the_demos_is_not_clipped():
  obs, _, norm = _fit()
  far = obs[:1].copy()
  far[0, 0] = 3.0  # the demonstrations span [0, 1]: 1.2 with the margin, centred at 0.5
  np.testing.assert_allclose(np.asarray(norm.normalize_obs(far))[0, 0], (3.0 - 0.5) * 2 / 1.2, rtol=1e-5)  # 4.17


def test_span_floors_bound_the_gain_of_a_barely_moving_dimension():
  obs, _, norm = _fit(min_span=np.array([0.5, 0.5, 0.5]))
  scale = np.asarray(norm.obs_scale)
  np.testing.assert_allclose(scale[:2], [2 / 1.2, 2 / 12.0], rtol=1e-5)  # wider than the floor: as before
  np.testing.assert_allclose(scale[2], 2 / 0.5, rtol=1e-6)  # constant: the floor's gain, 4
  np.testing.assert_allclose(np.asarray(norm.normalize_obs(obs))[:, 2], 0.0, atol=1e-6)  # centred
  # The tasks' floors: no policy-observation dimension gets a gain beyond 2 / its kind's span.
  assert max(2 / s for s in observations.MIN_SPAN.values()) == 50.0


def test_out_of_range_fraction_on_a_hand_made_batch():
  obs, _, norm = _fit()
  batch = np.tile(obs[:4], (2, 1, 1))  # (2 episodes, 4 frames, 3)
  batch[0, 1, 0] = 5.0  # one feature out of range in an acted-on frame
  batch[1, 3, :] = 100.0  # three in a frame after the episode ended
  assert abs(float(norm.out_of_range_fraction(batch)) - 4 / 24) < 1e-6
  acted = np.array([[True] * 4, [True, True, False, False]])
  assert abs(float(norm.out_of_range_fraction(batch, acted)) - 1 / 18) < 1e-6


def test_image_obs_keep_low_dim_scaling_and_map_pixels_to_0_1():
  """Image observations keep their low-dim scaling and map pixels to the unit interval [0, 1]."""
  obs = np.array([[0.0, 10.0], [1.0, 20.0]])
  norm = normalizer.fit(obs, np.zeros((2, 4)), margin=0.0)
  images = np.array([[[[0, 128, 255]]]], np.uint8)  # (1, 1, 1, 3)
  out = norm.normalize_obs({"lowdim": jnp.asarray(obs[:1]), "images": {"agentview_image": jnp.asarray(images)}})
  np.testing.assert_allclose(out["lowdim"], norm.normalize_obs(jnp.asarray(obs[:1])))
  np.testing.assert_allclose(out["images"]["agentview_image"][0, 0, 0], [0.0, 128 / 255, 1.0], rtol=1e-6)
  assert out["images"]["agentview_image"].dtype == jnp.float32
  beyond = {"lowdim": jnp.asarray([[2.0, 15.0]]), "images": {"agentview_image": jnp.asarray(images)}}
  assert float(norm.out_of_range_fraction(beyond)) == 0.5  # of the low-dim vector alone


def _lift_box():
  from soe_jax.data.spec import PolicySpec
  from soe_jax.envs import registry

  spec = PolicySpec.from_dict(registry.task_spec("lift", "absolute"))
  return spec, spec.action_bounds()


def test_the_workspace_box_maps_to_unit_range_and_the_loss_sees_an_action_beyond_the_demos_unclipped():
  """Demonstrations spanning y in [-0.01, 0.02]; a buffer episode commanding y = 0.05, outside their
  widened range but inside Lift's workspace: the batch the loss sees un-normalises to it within 1e-6
  (under the demonstrations' range it would be clipped to 0.023)."""
  import jax

  from soe_jax.data import buffer as buffer_lib
  from soe_jax.train import fit

  spec, (lo, hi) = _lift_box()
  rng = np.random.default_rng(0)
  demos = np.tile(np.r_[0.0, 0.0, 0.9, np.zeros(6), 1.0], (200, 1)).astype(np.float32)
  demos[:, 1] = rng.uniform(-0.01, 0.02, 200)
  norm = normalizer.fit(np.zeros((200, 2)), demos, 0.1, action_box=(lo, hi))
  corners = np.asarray(
    norm.normalize_actions(np.stack([np.where(np.isfinite(lo), lo, 0), np.where(np.isfinite(hi), hi, 0)]))
  )
  np.testing.assert_allclose(corners[:, :3], [[-1] * 3, [1] * 3], atol=1e-6)  # the box is [-1, 1]
  target = np.r_[0.02, 0.05, 0.95, np.zeros(6), -1.0].astype(np.float32)
  assert lo[1] < 0.05 < hi[1]
  buf = buffer_lib.create(4, 32, 2, 10)
  buf = buffer_lib.add(buf, np.zeros((1, 32, 2)), np.tile(target, (1, 32, 1)), np.array([32]), np.ones(1, bool), 1)
  raw = buffer_lib.sample_windows(buf, jax.random.key(0), 8, 16, 2, 8)
  seen = fit.training_batch(norm, raw)["actions"]
  np.testing.assert_allclose(np.asarray(norm.unnormalize_actions(seen)), np.broadcast_to(target, seen.shape), atol=1e-6)
  old = normalizer.fit(np.zeros((200, 2)), demos, 0.1)  # the demonstrations' range clips it
  assert abs(float(old.unnormalize_actions(old.normalize_actions(target))[1]) - 0.05) > 0.02
