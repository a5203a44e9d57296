"""Steering's math: SNR on synthetic latents, farthest point sampling against brute force, proposals."""

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax.explore import steering


def test_snr_on_synthetic_latents_with_known_variances():
  key_mu, _ = jax.random.split(jax.random.PRNGKey(0))
  n = 20000
  signal_std = jnp.array([1.0, 0.1, 3.0])
  noise_std = jnp.array([0.5, 1.0, 3.0])
  mu = signal_std * jax.random.normal(key_mu, (n, 3))
  log_std = jnp.broadcast_to(jnp.log(noise_std), (n, 3))
  expected = 10 * np.log10(np.asarray(signal_std) ** 2 / np.asarray(noise_std) ** 2)  # 6.02, -20, 0
  np.testing.assert_allclose(steering.snr_db(mu, log_std), expected, atol=0.1)
  assert steering.effective_dims(jnp.asarray(expected) + 0.01) == (0, 2)  # 6.03 dB, then 0.01 dB


def _greedy_reference(paths, num, first=0):
  """Farthest point sampling the slow way: every candidate against every chosen path, in Python."""
  paths = np.asarray(paths)
  chosen = [first]
  while len(chosen) < num:
    best, best_d = None, -1.0
    for i in range(len(paths)):
      if i in chosen:
        continue
      d = min(np.mean(np.linalg.norm(paths[i] - paths[j], axis=-1)) for j in chosen)
      if d > best_d:
        best, best_d = i, d
    chosen.append(best)
  return chosen


def test_farthest_points_match_brute_force_and_never_repeat():
  """Farthest point sampling matches brute force and never repeats a point."""
  for seed in range(5):
    paths = jax.random.normal(jax.random.PRNGKey(seed), (12, 8, 3))
    got = [int(i) for i in steering.farthest_point_sampling(paths, 5)]
    assert got == _greedy_reference(paths, 5)
    assert len(set(got)) == 5
  # All proposals identical: still distinct indices.
  same = jnp.zeros((6, 4, 3))
  assert sorted(int(i) for i in steering.farthest_point_sampling(same, 6)) == list(range(6))


def test_farthest_point_sampling_spreads_out():
  # Points on a line: picking 3 of 0..10 from 0 gives the ends and the middle.
  paths = jnp.arange(11.0)[:, None, None] * jnp.ones((11, 2, 3))
  assert [int(i) for i in steering.farthest_point_sampling(paths, 3)] == [0, 10, 5]


def test_dimension_proposals_vary_only_that_dimension():
  mu, log_std = jnp.array([0.5, -1.0, 2.0]), jnp.log(jnp.array([0.1, 0.2, 0.3]))
  z = steering.dimension_proposals(mu, log_std, 1, jax.random.PRNGKey(0), 4000, alpha=2.0)
  np.testing.assert_array_equal(z[:, 0], 0.5)
  np.testing.assert_array_equal(z[:, 2], 2.0)
  np.testing.assert_allclose([float(z[:, 1].mean()), float(z[:, 1].std())], [-1.0, 0.4], atol=0.02)


def test_two_robots_paths_are_compared_arm_by_arm():
  """(P, T, R, 3) paths: the distance is each arm's mean distance, averaged over the arms; an action's
  positions are the first 3 numbers of each robot's block."""
  from soe_jax.envs import observations

  rng = np.random.default_rng(0)
  actions = jnp.asarray(rng.normal(size=(5, 8, 20)), jnp.float32)
  paths = observations.action_positions(actions, 2)
  np.testing.assert_array_equal(paths[:, :, 1], actions[:, :, 10:13])
  per_arm = [steering.path_distances(paths[:, :, k]) for k in range(2)]
  np.testing.assert_allclose(steering.path_distances(paths), (per_arm[0] + per_arm[1]) / 2, rtol=1e-5)
