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
