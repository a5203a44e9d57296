"""robomimic HDF5 layout: written, read back exactly, and clear errors for bad files."""

import json

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
    next_obs={
      "robot0_eef_pos": rng.normal(size=(t, 3)).astype(np.float32),
      "object": rng.normal(size=(t, 10)).astype(np.float32),
    },
    states=rng.normal(size=(t, 1 + 16 + 15)),  # float64 [time, qpos, qvel]
  )


def test_round_trip_is_exact(tmp_path):
  rng = np.random.default_rng(0)
  episodes = [_episode(rng, t) for t in (5, 9, 12)]
  episodes[1]["success"] = False
  path = str(tmp_path / "demos.hdf5")
  hdf5.write_episodes(path, episodes, {"env_name": "lift", "source": "test"})
  back, env_args = hdf5.read_episodes(path)
  assert env_args == {
    "env_name": "Lift",
    "type": 1,
    "env_kwargs": {},
    "soe_jax": {"env_name": "lift", "source": "test"},
  }
  assert len(back) == 3 and [ep["success"] for ep in back] == [True, False, True]
  for a, b in zip(episodes, back):
    np.testing.assert_array_equal(a["actions"], b["actions"])
    assert b["states"].dtype == np.float64
    np.testing.assert_array_equal(a["states"], b["states"])
    for group in ("obs", "next_obs"):
      assert a[group].keys() == b[group].keys()
      for k in a[group]:
        np.testing.assert_array_equal(a[group][k], b[group][k])
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


# What robomimic's readers take from a file (soe_jax/data/hdf5.py's docstring, with robomimic's lines):
# per data/demo_<i>: these datasets, obs and next_obs with the same keys and T rows, num_samples = T.
ROBOMIMIC_DEMO_DATASETS = {"actions": 2, "rewards": 1, "dones": 1, "states": 2}


def _check_robomimic_layout(path, obs_keys):
  """The file as robomimic reads it (file_utils.get_env_metadata_from_dataset, dataset.load_demo_info
  and load_dataset_in_memory, file_utils.get_demos_for_filter_key), asserted."""
  with h5py.File(path, "r") as f:
    meta = json.loads(f["data"].attrs["env_args"])
    assert isinstance(meta["env_name"], str) and meta["type"] in (1, 2, 3) and isinstance(meta["env_kwargs"], dict)
    demos = list(f["data"].keys())
    order = np.argsort([int(d[5:]) for d in demos])  # robomimic's sort
    total = 0
    for d in (demos[i] for i in order):
      g = f[f"data/{d}"]
      t = int(g.attrs["num_samples"])
      total += t
      for k, ndim in ROBOMIMIC_DEMO_DATASETS.items():
        assert g[k].ndim == ndim and g[k].shape[0] == t, (d, k)
        g[k][()].astype("float32")
      assert g["states"].dtype == np.float64
      for group in ("obs", "next_obs"):
        assert sorted(g[group].keys()) == sorted(obs_keys) and all(g[group][k].shape[0] == t for k in obs_keys)
    assert f["data"].attrs["total"] == total
    masks = {k: [e.decode("utf-8") for e in np.array(f[f"mask/{k}"][:])] for k in f.get("mask", {})}
    assert all(f[f"mask/{k}"].dtype.kind == "S" for k in masks)
    return meta, masks


def test_robomimic_reads_the_file_and_its_masks_choose_episodes(tmp_path):
  """The written file is what robomimic reads, and its masks choose episodes."""
  rng = np.random.default_rng(1)
  episodes = [_episode(rng, t) for t in (4, 6, 8, 10)]
  del episodes[2]["next_obs"]  # an episode from an older file: next_obs is the following step's obs
  path = str(tmp_path / "kept.hdf5")
  meta = {"env_name": "can", "env_kwargs": {"episode_length": 400}, "round": 1}
  hdf5.write_episodes(path, episodes, meta, masks={"train_0.5": [3, 1], "demos": [0]})
  env_args, masks = _check_robomimic_layout(path, ["robot0_eef_pos", "object"])
  assert env_args["env_name"] == "PickPlaceCan" and env_args["env_kwargs"] == {"episode_length": 400}
  assert masks == {"demos": ["demo_0"], "train_0.5": ["demo_1", "demo_3"]}
  chosen, _ = hdf5.read_episodes(path, filter_key="train_0.5")
  assert [len(ep["actions"]) for ep in chosen] == [6, 10]
  back, _ = hdf5.read_episodes(path)
  np.testing.assert_array_equal(back[2]["next_obs"]["object"][:-1], episodes[2]["obs"]["object"][1:])
  np.testing.assert_array_equal(back[2]["next_obs"]["object"][-1], episodes[2]["obs"]["object"][-1])
  with pytest.raises(ValueError, match=r"no filter key 'core_20'; its filter keys: demos, train_0.5"):
    hdf5.read_episodes(path, filter_key="core_20")
  with pytest.raises(ValueError, match=r"mask 'x' names episodes outside 0..3"):
    hdf5.write_episodes(str(tmp_path / "bad.hdf5"), episodes, meta, masks={"x": [4]})
  assert not (tmp_path / "bad.hdf5").exists()


def test_images_travel_under_robomimics_image_keys_as_uint8(tmp_path):
  rng = np.random.default_rng(0)
  images = rng.integers(0, 256, (5, 84, 84, 3), np.uint8)
  ep = dict(
    obs={"robot0_eef_pos": rng.normal(size=(5, 3)).astype(np.float32), "agentview_image": images},
    actions=np.zeros((5, 10), np.float32),
  )
  path = str(tmp_path / "images.hdf5")
  hdf5.write_episodes(path, [ep], dict(env_name="lift"))
  with h5py.File(path) as f:
    assert f["data/demo_0/obs/agentview_image"].dtype == np.uint8
    np.testing.assert_array_equal(f["data/demo_0/next_obs/agentview_image"][:4], images[1:])
  back, _ = hdf5.read_episodes(path)
  assert back[0]["obs"]["agentview_image"].dtype == np.uint8
  np.testing.assert_array_equal(back[0]["obs"]["agentview_image"], images)
