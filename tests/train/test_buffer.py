"""Episode buffer: appending with provenance, and Diffusion Policy's window sampling with edge padding."""

import jax
import jax.numpy as jnp
import numpy as np

from soe_jax import buffer


def _episodes(lengths, d=2, a=1, max_length=30):
  n = len(lengths)
  obs = np.zeros((n, max_length, d), np.float32)
  actions = np.zeros((n, max_length, a), np.float32)
  for i, t in enumerate(lengths):
    obs[i, :t, 0] = np.arange(t)  # frame index, to check which frames a window holds
    obs[i, :t, 1] = i
    actions[i, :t, 0] = np.arange(t)
  return obs, actions, np.asarray(lengths, np.int32)


def test_add_keeps_only_selected_and_records_provenance():
  buf = buffer.create(4, 30, 2, 1)
  obs, actions, length = _episodes([10, 12, 20])
  buf = buffer.add(buf, obs, actions, length, jnp.array([True, False, True]), 0)
  assert int(buf.count) == 2
  np.testing.assert_array_equal(buf.length[:2], [10, 20])
  buf = buffer.add(buf, obs, actions, length, jnp.array([True, True, True]), 3)
  assert int(buf.count) == 4  # capacity reached: the third episode is dropped
  np.testing.assert_array_equal(buf.source, [0, 0, 3, 3])
  assert bool(buf.valid.all())


def test_window_counts_and_edge_padding():
  buf = buffer.create(2, 30, 2, 1)
  obs, actions, length = _episodes([20, 9])
  buf = buffer.add(buf, obs, actions, length, jnp.array([True, True]), 0)
  np.testing.assert_array_equal(buffer.num_windows(buf, 16, 2, 8), [13, 2])  # L - 7
  s = jax.jit(lambda k: buffer.sample_windows(buf, k, 4000, 16, 2, 8))(jax.random.PRNGKey(0))
  obs_w, act_w = np.asarray(s["obs"]), np.asarray(s["actions"])
  ep = obs_w[:, 0, 1].astype(int)
  # Windows are uniform over all 15 windows: episode 0 holds 13 of them.
  assert abs((ep == 0).mean() - 13 / 15) < 0.03
  first = act_w[:, 0, 0]
  # The first window starts one step before the episode: its first frame repeats frame 0.
  assert (first == 0).any()
  starts = act_w[:, 1, 0] - 1  # window start = frame of index 1 minus one (index 0 may be padded)
  assert starts.min() == -1
  # Frames past the end repeat the last one.
  short = ep == 1
  assert act_w[short, -1, 0].max() == 8 and (np.diff(act_w[short, :, 0], axis=1) >= 0).all()
  # Observations are the first two frames of the window, aligned with its actions.
  np.testing.assert_array_equal(obs_w[:, :, 0], act_w[:, :2, 0])
