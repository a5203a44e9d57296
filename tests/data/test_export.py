"""A run's data exported to robomimic's HDF5, Diffusion Policy's zarr and RLDS and read back: the same
episodes, groups and provenance, so a buffer built from them holds the same windows; and the `export`
and `inspect` commands."""

import os
import shutil
import types

import chex
import numpy as np
import pytest

from soe_jax.commands import export as export_command
from soe_jax.commands import inspect as inspect_command
from soe_jax.data import export, hdf5, inspect, lerobot
from soe_jax.data.episodes import build_buffer
from soe_jax.envs import observations
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime.errors import UserError


@pytest.fixture(scope="module")
def run_with_data(smoke_run, tmp_path_factory):
  """The smoke run, with a kept round 1 and a steered round 0 of (relabelled) demonstrations."""
  root, config, workdir, _ = smoke_run
  runs = tmp_path_factory.mktemp("export") / "runs"
  shutil.copytree(root, runs)  # the run beside its round 0
  copy = str(runs / os.path.basename(workdir))
  shutil.rmtree(os.path.join(copy, "data"), ignore_errors=True)  # (whatever the smoke run kept)
  run = RunDir.open(copy)
  demos = run.demonstrations()
  hdf5.write_episodes(run.data_path(1), demos[1:3], {"env_name": "lift", "round": 1})
  steered = [dict(demos[0], success=False), demos[3]]
  hdf5.write_episodes(run.steered_path(0), steered, {"env_name": "lift", "steered": True})
  return copy, config, len(demos)


def _buffer(config, sets):
  keys = observations.policy_obs_keys(1)  # lift's low-dim policy: its sizes and keys
  dims = types.SimpleNamespace(obs_dim=19, action_dim=10, image_keys=(), lowdim_keys=keys)
  return build_buffer(config, dims, sets)


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_an_export_reads_back_as_the_same_groups_and_buffer(run_with_data, tmp_path, fmt):
  if fmt == "rlds":
    pytest.importorskip("tensorflow_datasets", reason="the rlds extra is not installed: pip install -e '.[rlds]'")
  workdir, config, num_demos = run_with_data
  out = str(tmp_path / ("data.hdf5" if fmt == "robomimic" else f"data.{fmt}"))
  sets, meta = RunDir.open(workdir).fit_sets(2)
  export.write(out, fmt, sets, meta)
  assert [(s.source, s.steered, len(s.episodes)) for s in sets] == [(0, False, num_demos), (1, False, 2), (0, True, 1)]
  back, back_meta = export.load(out)
  assert back_meta == meta and meta["round"] == 2 and meta["env_name"] == "lift"
  assert [(s.source, s.steered, len(s.episodes)) for s in back] == [
    (s.source, s.steered, len(s.episodes)) for s in sets
  ]
  for a, b in zip([ep for s in sets for ep in s.episodes], [ep for s in back for ep in s.episodes]):
    for k in ("actions", "states"):
      assert a[k].dtype == b[k].dtype
      np.testing.assert_array_equal(a[k], b[k])
    for group in ("obs",) if fmt == "lerobot" else ("obs", "next_obs"):  # (LeRobot keeps no next observations)
      chex.assert_trees_all_equal(a[group], b[group])
    assert a.get("success", True) == b.get("success", True)
  chex.assert_trees_all_equal(_buffer(config, sets), _buffer(config, back))
  described = inspect.describe(out)
  assert ("filter key steered_0: 1 episodes" if fmt == "robomimic" else "steered_0: 1 episodes") in described
  if fmt == "lerobot":  # a robot's recorder's layout: success labels and each try's start state
    info, episodes = lerobot.read_dataset(out)
    assert info["fps"] == 20 and [ep["success"] for ep in episodes] == [
      ep.get("success", True) for s in sets for ep in s.episodes
    ]
    np.testing.assert_array_equal(episodes[0]["columns"]["start_state"][-1], sets[0].episodes[0]["states"][0])
  assert '"round": 2' in described and "states: (" in described and "float64" in described


def test_round_0_exports_demos_alone_and_bad_requests_say_why(run_with_data, tmp_path):
  workdir, _, num_demos = run_with_data
  run = RunDir.open(workdir)
  sets, meta = run.fit_sets(0)
  assert [(s.source, len(s.episodes)) for s in sets] == [(0, num_demos)] and meta["round"] == 0
  with pytest.raises(UserError, match=r"round 7 has no policy yet; its rounds with one are 0..2"):
    run.fit_sets(7)
  with pytest.raises(UserError, match="unknown format 'rlds2'; known formats: robomimic, zarr, rlds"):
    export.write(str(tmp_path / "x"), "rlds2", sets, meta)
  assert not os.path.exists(tmp_path / "x")
  (tmp_path / "empty.zarr").mkdir()
  with pytest.raises(ValueError, match="empty.zarr.*not Diffusion Policy's replay-buffer layout"):
    export.load(str(tmp_path / "empty.zarr"))


@pytest.fixture(autouse=True)
def fresh_flags():
  """Each test's command lines parsed from the defaults (a command's flags keep what the last parse set)."""
  export_command.FLAGS.unparse_flags()
  inspect_command.FLAGS.unparse_flags()


def test_export_and_inspect_write_and_describe_a_runs_data(run_with_data, tmp_path, capsys):
  """The `export` and `inspect` commands write and describe a run's data."""
  workdir, _, num_demos = run_with_data
  out = str(tmp_path / "data.hdf5")
  export_command.main(["python -m soe_jax export", f"--workdir={workdir}", "--format=robomimic", f"--out={out}"])
  assert capsys.readouterr().out == f"{out}: {num_demos + 3} episodes (demos: {num_demos}, round_1: 2, steered_0: 1)\n"
  inspect_command.main(["python -m soe_jax inspect", out])
  assert capsys.readouterr().out == inspect.describe(out)


@pytest.mark.parametrize(
  "argv, message",
  [
    (["--format=zarr", "--out=OUT"], "--workdir is required"),
    (["--workdir=RUN", "--format=hdf5", "--out=OUT"], "flag --format=hdf5: value should be one of"),
    (["--workdir=RUN", "--format=zarr", "--out=OUT", "--round=7"], "round 7 has no policy yet"),
    (["--workdir=RUN", "--format=zarr", "--out=OUT", "extra"], "unexpected arguments: extra"),
  ],
)
def test_a_bad_export_command_is_one_line_and_writes_nothing(run_with_data, tmp_path, capsys, argv, message):
  workdir, _, _ = run_with_data
  out = str(tmp_path / "x.zarr")
  argv = [a.replace("RUN", workdir).replace("OUT", out) for a in argv]
  with pytest.raises(SystemExit) as exit:
    export_command.main(["python -m soe_jax export", *argv])
  err = capsys.readouterr().err
  assert exit.value.code == 2 and err.startswith("error: ") and message in err and err.count("\n") == 1, err
  assert not os.path.exists(out)


def test_inspect_says_what_it_cannot_read(tmp_path, capsys):
  (tmp_path / "notes.hdf5").write_text("not HDF5")
  for path, message in ((tmp_path / "absent.hdf5", "does not exist"), (tmp_path / "notes.hdf5", "not HDF5, zarr")):
    with pytest.raises(SystemExit) as exit:
      inspect_command.main(["python -m soe_jax inspect", str(path)])
    err = capsys.readouterr().err
    assert exit.value.code == 2 and err.startswith("error: ") and message in err and err.count("\n") == 1, err
