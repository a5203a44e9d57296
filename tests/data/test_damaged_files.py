"""Every reader of a file from outside (robomimic HDF5, a LeRobotDataset, a zarr replay buffer, an RLDS
dataset, a config file), given one that is
empty, truncated, damaged inside, of the wrong layout, a directory or missing, refuses it with one message
naming the file (a `ValueError`; the commands print it on one line and exit with status 2)."""

import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from soe_jax.data import export, hdf5, lerobot, rlds, zarr_store
from soe_jax.data.episodes import EpisodeSet
from soe_jax.runtime import configfile

EPISODE = dict(obs={"x": np.arange(30, dtype=np.float32).reshape(10, 3)}, actions=np.zeros((10, 4), np.float32))


def _damage(path: str, how: str) -> None:
  data = open(path, "rb").read()
  if how == "empty":
    open(path, "wb").close()
  elif how == "truncated":
    open(path, "wb").write(data[: len(data) // 2])
  elif how == "damaged inside":  # the HDF5 object headers and B-trees overwritten (raw numbers carry no checksum)
    b = bytearray(data)
    for sig in (b"OHDR", b"TREE", b"HEAP", b"SNOD"):
      at = b.find(sig, 100)
      while at >= 0:
        b[at : at + 24] = bytes(24)
        at = b.find(sig, at + 24)
    open(path, "wb").write(bytes(b))


@pytest.mark.parametrize("how", ["empty", "truncated", "damaged inside", "wrong layout", "a directory", "missing"])
def test_hdf5(tmp_path, how):
  path = str(tmp_path / "demos.hdf5")
  if how == "wrong layout":
    with h5py.File(path, "w") as f:
      f.create_group("observations")
  elif how == "a directory":
    os.makedirs(path)
  elif how != "missing":
    hdf5.write_episodes(path, [EPISODE], {"env_name": "lift"})
    _damage(path, how)
  error = FileNotFoundError if how == "missing" else ValueError
  with pytest.raises(error, match="demos.hdf5"):
    hdf5.read_episodes(path)
  with pytest.raises(error, match="demos.hdf5"):  # (`inspect`'s reader)
    export.load(path)


@pytest.mark.parametrize("how", ["info empty", "info not JSON", "data truncated", "data damaged", "no episode rows",
                                 "an empty directory", "missing"])  # fmt: skip
def test_lerobot(tmp_path, how):
  root = str(tmp_path / "data")
  lerobot.write_dataset(root, [dict(obs={"observation.state": EPISODE["obs"]["x"]}, actions=EPISODE["actions"])], 10)
  parquet = os.path.join(root, "data", "chunk-000", "file-000.parquet")
  info = os.path.join(root, "meta", "info.json")
  if how == "info empty":
    open(info, "w").close()
  elif how == "info not JSON":
    open(info, "w").write('{"fps": 10, "feat')
  elif how == "data truncated":
    _damage(parquet, "truncated")
  elif how == "data damaged":
    b = bytearray(open(parquet, "rb").read())
    b[100:400] = np.random.default_rng(0).bytes(300)
    open(parquet, "wb").write(bytes(b))
  elif how == "no episode rows":
    shutil.rmtree(os.path.join(root, "meta", "episodes"))
  elif how == "an empty directory":
    shutil.rmtree(root)
    os.makedirs(root)
  else:
    shutil.rmtree(root)
  with pytest.raises(lerobot.DatasetError, match=str(tmp_path / "data")):
    lerobot.read_dataset(root)


FULL = dict(EPISODE, next_obs=EPISODE["obs"], states=np.zeros((10, 5)))


def _damage_files(root: str, how: str, pick) -> None:
  """Damage the files under `root` that `pick(name)` chooses: emptied, cut in half or partly overwritten."""
  for parent, _, files in os.walk(root):
    for name in files:
      if pick(name):
        path = os.path.join(parent, name)
        if how == "damaged inside":
          b = bytearray(open(path, "rb").read())
          at = min(400, len(b) // 4)  # (an RLDS record file's data, before its zero padding)
          b[at : at + 64] = np.random.default_rng(0).bytes(len(b[at : at + 64]))
          open(path, "wb").write(bytes(b))
        else:
          _damage(path, how)


@pytest.mark.parametrize("how", ["metadata empty", "metadata truncated", "chunks truncated", "chunks damaged inside",
                                 "wrong layout", "a file", "missing"])  # fmt: skip
def test_zarr(tmp_path, how):
  path = str(tmp_path / "replay.zarr")
  if how == "a file":
    open(path, "w").write("x")
  elif how != "missing":
    zarr_store.write(path, [EpisodeSet([FULL], 0)], {"env_name": "lift"})
    if how == "wrong layout":
      shutil.rmtree(os.path.join(path, "meta"))
    elif how.startswith("metadata"):
      _damage_files(path, how.split()[1], lambda name: name.startswith(".z"))
    else:
      _damage_files(path, how.split(maxsplit=1)[1], lambda name: not name.startswith("."))
  error = FileNotFoundError if how == "missing" else ValueError
  with pytest.raises(error, match="replay.zarr"):
    zarr_store.read(path)


@pytest.mark.parametrize("how", ["records truncated", "records damaged inside", "records empty", "schema empty",
                                 "wrong layout", "missing"])  # fmt: skip
def test_rlds(tmp_path, how):
  path = str(tmp_path / "rlds")
  if how != "missing":
    rlds.write(path, [EpisodeSet([FULL], 0)], {"env_name": "lift"})
    if how == "wrong layout":
      shutil.rmtree(os.path.join(path, rlds.NAME))
      os.makedirs(os.path.join(path, rlds.NAME))
    elif how.startswith("records"):
      _damage_files(path, how.split(maxsplit=1)[1], lambda name: "array_record" in name)
    else:
      _damage_files(path, "empty", lambda name: name == "features.json")
  with pytest.raises(ValueError, match=str(tmp_path / "rlds")):
    rlds.read(path)


@pytest.mark.parametrize("how", ["empty", "not Python", "binary", "no get_config", "a directory", "missing"])
def test_config_file(tmp_path, how):
  path = str(tmp_path / "mine.py")
  content = {"empty": "", "not Python": "def get_config(:\n", "binary": b"\x00\xff\xfe", "no get_config": "x = 1\n"}
  if how in content:
    data = content[how]
    open(path, "wb").write(data if isinstance(data, bytes) else data.encode())
  elif how == "a directory":
    os.makedirs(path)
  with pytest.raises(ValueError, match="mine.py"):
    configfile.load(path)


def test_a_command_says_it_in_one_line_and_writes_nothing(tmp_path):
  config = tmp_path / "mine.py"
  config.write_text("def get_config(:\n")
  workdir = tmp_path / "run"
  r = subprocess.run([sys.executable, "-m", "soe_jax", "run", f"--config={config}", f"--workdir={workdir}"],
                     capture_output=True, text=True, timeout=120)  # fmt: skip
  assert r.returncode == 2 and r.stderr.strip().splitlines() == [
    f"error: config file '{config}': line 1: invalid syntax"
  ]
  assert not workdir.exists()
