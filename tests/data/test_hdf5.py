"""robomimic HDF5 layout: written, read back exactly, and clear errors for bad files."""

import h5py
import numpy as np
import pytest

from soe_jax.data import hdf5


def _episode(rng, t):
  return dict(
    obs={
      "robot0_eef_pos": rng.normal(size=(t, 3)).astype(np.float32),
      "object": rng.normal(size=(t, 10)).astype(np.float32),
    },
    actions=rng.normal(size=(t, 10)).astype(np.float32),
    states=rng.normal(size=(t, 16)).astype(np.float32),
  )


def test_round_trip_is_exact(tmp_path):
  rng = np.random.default_rng(0)
  episodes = [_episode(rng, t) for t in (5, 9, 12)]
  episodes[1]["success"] = False
  path = str(tmp_path / "demos.hdf5")
  hdf5.write_episodes(path, episodes, env_args={"env_name": "lift"})
  back, env_args = hdf5.read_episodes(path)
  assert env_args == {"env_name": "lift"}
  assert len(back) == 3 and [ep["success"] for ep in back] == [True, False, True]
  for a, b in zip(episodes, back):
    np.testing.assert_array_equal(a["actions"], b["actions"])
    np.testing.assert_array_equal(a["states"], b["states"])
    assert a["obs"].keys() == b["obs"].keys()
    for k in a["obs"]:
      np.testing.assert_array_equal(a["obs"][k], b["obs"][k])
  with h5py.File(path) as f:  # robomimic's attributes
    assert f["data"].attrs["total"] == 26
    assert f["data/demo_1"].attrs["num_samples"] == 9
    assert f["data/demo_2/rewards"][-1] == 1.0 and f["data/demo_2/dones"][-1] == 1
    assert f["data/demo_1/dones"][-1] == 0


def test_missing_and_corrupt_files_say_which_and_why(tmp_path):
  with pytest.raises(FileNotFoundError, match="nope.hdf5"):
    hdf5.read_episodes(str(tmp_path / "nope.hdf5"))
  bad = tmp_path / "bad.hdf5"
  bad.write_bytes(b"not hdf5 at all")
  with pytest.raises(ValueError, match="bad.hdf5.*not a readable HDF5"):
    hdf5.read_episodes(str(bad))
  empty = tmp_path / "empty.hdf5"
  with h5py.File(empty, "w") as f:
    f.create_group("other")
  with pytest.raises(ValueError, match="no 'data' group"):
    hdf5.read_episodes(str(empty))
