"""Per-dimension limits with a margin; identity for rotation-6d and gripper; clipping reported."""

import numpy as np

from soe_jax.policies import normalizer


def test_limits_with_margin_identity_dims_and_clip_fraction():
  rng = np.random.default_rng(0)
  obs = rng.uniform([0, -5, 2], [1, 5, 2], size=(500, 3)).astype(np.float32)  # third dim constant
  actions = rng.uniform(-0.5, 0.5, size=(500, 10)).astype(np.float32)
  norm = normalizer.fit(obs, actions, margin=0.1)
  y = np.asarray(norm.normalize_obs(obs))
  # The data's range maps to [-1/1.2, 1/1.2]: 10% margin on each side.
  np.testing.assert_allclose(y[:, :2].max(0), 1 / 1.2, atol=1e-3)
  np.testing.assert_allclose(y[:, :2].min(0), -1 / 1.2, atol=1e-3)
  np.testing.assert_allclose(y[:, 2], 0.0, atol=1e-6)  # a constant dim is only shifted
  a = np.asarray(norm.normalize_actions(actions))
  np.testing.assert_array_equal(a[:, 3:], actions[:, 3:])  # rotation-6d and gripper as they are
  np.testing.assert_allclose(np.asarray(norm.unnormalize_actions(a)), actions, atol=1e-5)
  assert float(norm.obs_clip_fraction(obs)) == 0.0
  outside = obs.copy()
  outside[:, 0] += 2.0
  assert abs(float(norm.obs_clip_fraction(outside)) - 1 / 3) < 1e-6
