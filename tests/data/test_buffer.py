"""Episode buffer: appending with provenance, and Diffusion Policy's window sampling with edge padding."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from soe_jax.data import buffer


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


def _frame_images(lengths, size=4):
  """Each episode's images {key: (T, size, size, 3) uint8}, pixel (0, 0) holding (frame, episode, key)."""
  out = []
  for i, t in enumerate(lengths):
    ims = {}
    for j, k in enumerate(("agentview_image", "robot0_eye_in_hand_image")):
      im = np.zeros((t, size, size, 3), np.uint8)
      im[:, 0, 0] = np.stack([np.arange(t), np.full(t, i), np.full(t, j)], -1)
      ims[k] = im
    out.append(ims)
  return out


def test_images_stored_unpadded_and_windows_read_their_frames():
  """Images are stored unpadded, and each window reads the frames of its observations."""
  lengths = [20, 9, 14]
  buf = buffer.create(4, 30, 2, 1)
  obs, actions, length = _episodes(lengths)
  buf = buffer.add(buf, obs, actions, length, jnp.ones(3, bool), 0)
  buf = buffer.with_images(buf, _frame_images(lengths), image_frames=50)
  assert buf.images["agentview_image"].shape == (50, 4, 4, 3) and buf.images["agentview_image"].dtype == jnp.uint8
  np.testing.assert_array_equal(buf.first_frame[:3], [0, 20, 29])
  s = jax.jit(lambda k: buffer.sample_windows(buf, k, 2000, 16, 2, 8))(jax.random.PRNGKey(1))
  low, images = np.asarray(s["obs"]["lowdim"]), {k: np.asarray(v) for k, v in s["obs"]["images"].items()}
  assert images["robot0_eye_in_hand_image"].shape == (2000, 2, 4, 4, 3)
  for j, k in enumerate(("agentview_image", "robot0_eye_in_hand_image")):
    pixel = images[k][:, :, 0, 0].astype(np.float32)  # (B, To, 3)
    np.testing.assert_array_equal(pixel[..., 0], low[..., 0])  # the same frame as the low-dim obs,
    np.testing.assert_array_equal(pixel[..., 1], low[..., 1])  # edge padding included, of the same episode
    assert (pixel[..., 2] == j).all()


def test_images_beyond_the_frame_store_are_refused():
  buf = buffer.create(2, 30, 2, 1)
  obs, actions, length = _episodes([20, 9])
  buf = buffer.add(buf, obs, actions, length, jnp.ones(2, bool), 0)
  with pytest.raises(ValueError, match="29 frames of images do not fit in data.image_frames=25; raise it"):
    buffer.with_images(buf, _frame_images([20, 9]), image_frames=25)


def _demos_and_own(lengths_demo=(30, 40), lengths_own=(25, 37, 50)):
  """Two demonstrations and three self-collected episodes (round 1), obs = the step index, actions =
  the step index in dim 0 and the episode's number in dim 1."""
  buf = buffer.create(8, 50, 1, 2)
  for source, lengths in ((0, lengths_demo), (1, lengths_own)):
    n = len(lengths)
    t = np.broadcast_to(np.arange(50, dtype=np.float32), (n, 50))
    first = int(buf.count)
    ep = np.broadcast_to(np.arange(first, first + n, dtype=np.float32)[:, None], (n, 50))
    buf = buffer.add(buf, t[..., None], np.stack([t, ep], -1), np.array(lengths), np.ones(n, bool), source)
  return buf


def test_demo_fraction_draws_that_share_of_each_batch_from_the_demonstrations():
  buf = _demos_and_own()
  sampling = buffer.Sampling(demo_fraction=0.5)
  out = jax.jit(lambda k: buffer.sample_windows(buf, k, 10_000, 16, 2, 8, sampling))(jax.random.key(0))
  episode = np.asarray(out["actions"][:, 0, 1])
  share = np.mean(episode < 2)  # episodes 0 and 1 are the demonstrations
  assert abs(share - 0.5) <= 0.02, share
  assert set(np.unique(episode)) == {0, 1, 2, 3, 4}
  uniform = np.asarray(buffer.sample_windows(buf, jax.random.key(0), 10_000, 16, 2, 8)["actions"][:, 0, 1])
  assert abs(np.mean(uniform < 2) - (23 + 33) / (23 + 33 + 18 + 30 + 43)) < 0.02  # by window count otherwise


def test_aligned_windows_start_self_collected_windows_at_decisions_only():
  """Every window of a self-collected episode has its executed part (actions To-1 .. To-1+Ta-1) start at
  a decision (a multiple of Ta) and none is missed; demonstrations keep every start."""
  to, ta, h = 2, 8, 16
  buf = _demos_and_own()
  counts = np.asarray(buffer.num_windows(buf, h, to, ta, aligned=True))
  total = int(counts.sum())
  out = buffer.windows(buf, np.arange(total), h, to, ta, aligned=True)
  episode = np.asarray(out["actions"][:, 0, 1]).astype(int)
  executed_start = np.asarray(out["actions"][:, to - 1, 0]).astype(int)
  for e, length in zip(range(2, 5), (25, 37, 50)):
    starts = executed_start[episode == e]
    assert np.all(starts % ta == 0), starts
    assert sorted(starts) == list(range(0, length - h + ta + to - 1, ta))  # every decision a full window reaches
  plain = np.asarray(buffer.num_windows(buf, h, to, ta))
  np.testing.assert_array_equal(counts[:2], plain[:2])  # demonstrations: every start
