"""A run's directory on the toy task (`toy.py`): its config saved, and a changed, renamed or extended one
refused or accepted; fields added since read as their old behaviour; workdir names and what a run says
when it starts; the steered episodes the next fit takes."""

import json
import os
import shutil

import numpy as np
import pytest
import toy
import toy_config

from soe_jax.data import hdf5
from soe_jax.experiment import loop, rundir, schema
from soe_jax.experiment.rundir import RunDir

pytestmark = pytest.mark.usefixtures("toy_task")

SPEC = f"{toy_config.__file__}:smoke,soe"  # the toy task's config file, as `--config=` names one


def test_changed_config_is_refused_naming_fields(toy_run):
  _, _, workdir = toy_run
  changed = toy.get_config("smoke,soe")
  changed.explore.strategy.kwargs.alpha = 3.0
  changed.fit.lr = 1e-3
  with pytest.raises(ValueError, match=r"explore\.strategy\.kwargs\.alpha: 2\.0 -> 3\.0[\s\S]*fit\.lr"):
    loop.run(changed, workdir, progress=False)


def test_logging_settings_do_not_block_a_resume(toy_run):
  """Nor do they rename the run."""
  _, _, workdir = toy_run
  logged = toy.get_config("smoke,soe")
  logged.log.wandb = True
  rundir.check_config(workdir, logged)  # no mismatch: logging is not part of the run
  assert rundir.default_workdir(logged, SPEC) == os.path.join("runs", "toy-soe-seed0")


def test_the_same_command_names_the_same_workdir(toy_run, tmp_path):
  """... and the run says whether it starts, resumes (after which phase) or has finished."""
  _, config, workdir = toy_run
  assert rundir.default_workdir(config, SPEC) == os.path.join("runs", "toy-soe-seed0")
  other = toy.get_config("smoke,soe")
  other.fit.lr = 1e-3
  named = rundir.default_workdir(other, SPEC)
  assert named.startswith(os.path.join("runs", "toy-soe-seed0-")) and named == rundir.default_workdir(other, SPEC)
  other.seed = 3
  assert rundir.default_workdir(other, SPEC).startswith(os.path.join("runs", "toy-soe-seed3-"))
  assert rundir.status(str(tmp_path / "new"), config) == "starting"
  assert rundir.status(workdir, config).startswith("already finished (2 rounds)")
  partial = tmp_path / "partial"
  shutil.copytree(workdir, partial, ignore=shutil.ignore_patterns("rounds", "data", "tb"))
  lines = (partial / "metrics.jsonl").read_text().splitlines()[:3]
  (partial / "metrics.jsonl").write_text("\n".join(lines) + "\n")
  assert rundir.status(str(partial), config) == "resuming after round 1 explore"


def test_a_finished_run_takes_more_rounds(tmp_path):
  """More rounds are accepted (and saved); fewer are refused."""
  saved = toy.get_config("smoke")
  rundir.check_config(str(tmp_path), saved)
  more = toy.get_config("smoke")
  more.rounds.num_rounds = saved.rounds.num_rounds + 1
  rundir.check_config(str(tmp_path), more)  # accepted, and saved
  assert rundir.load_config(str(tmp_path)).rounds.num_rounds == saved.rounds.num_rounds + 1
  with pytest.raises(ValueError, match="rounds.num_rounds"):
    rundir.check_config(str(tmp_path), saved)  # fewer rounds than saved: refused


def test_renamed_fields_are_refused_naming_them(tmp_path):
  """A workdir saved before fields were renamed cannot be resumed or opened."""
  config = toy.get_config("smoke")
  saved = rundir.plain(config)
  saved["env"]["horizon"] = saved["env"].pop("episode_length")
  saved["explore"].update(method="soe", alpha=2.0, steer=dict(every=1))
  (tmp_path / "config.json").write_text(json.dumps(saved))
  message = (
    r"renamed:\n  env.horizon -> env.episode_length\n  explore.alpha -> [\s\S]*explore.steer -> [\s\S]*new --workdir"
  )
  with pytest.raises(ValueError, match=message):
    loop.run(config, str(tmp_path), progress=False)
  with pytest.raises(ValueError, match="explore.method -> method"):
    rundir.load_config(str(tmp_path))


def test_added_fields_read_as_their_old_behaviour(tmp_path):
  """A workdir saved before fields were added resumes; a different value is still a different config."""
  config = toy.get_config("smoke")
  saved = rundir.plain(config)
  assert {"rounds.steered", "rounds.refit_ema", "fit.eval_every", "policy.bypass.batch_fraction"} <= set(schema.ADDED)
  for field in schema.ADDED:  # a config saved before any of them existed
    *sections, name = field.split(".")
    d = saved
    for part in sections:
      d = d[part]
    del d[name]
  (tmp_path / "config.json").write_text(json.dumps(saved))
  # The one added field whose default changed since: such a workdir is on the demonstrations' range.
  with pytest.raises(ValueError, match="policy.action_range: 'demonstrations' -> 'workspace'"):
    rundir.check_config(str(tmp_path), config)
  config.policy.action_range = "demonstrations"
  rundir.check_config(str(tmp_path), config)  # accepted as it is
  assert rundir.load_config(str(tmp_path)).rounds.steered == "successful"
  del saved["explore"]["strategy"]["kwargs"]["hold"]  # soe's settings: likewise
  (tmp_path / "config.json").write_text(json.dumps(saved))
  assert rundir.load_config(str(tmp_path)).explore.strategy.kwargs.hold == 1
  config.rounds.steered = "all"  # a different value is still a different config
  with pytest.raises(ValueError, match="rounds.steered: 'successful' -> 'all'"):
    rundir.check_config(str(tmp_path), config)
  evaluated = toy.get_config("smoke")
  evaluated.fit.eval_every = 10  # in-fit evaluations leave round 0 as it is
  assert rundir.round0_key(evaluated) == rundir.round0_key(toy.get_config("smoke"))


def test_next_fit_takes_successful_steered_episodes(tmp_path):
  """Only the successful ones, unless told to take all."""
  config = toy.get_config("smoke,soe")
  run = RunDir(str(tmp_path), config)
  episode = lambda ok: dict(obs={"a": np.zeros((3, 2))}, actions=np.zeros((3, 10)), success=ok)
  hdf5.write_episodes(run.steered_path(0), [episode(True), episode(False), episode(True)], dict(steered=True))
  assert [len(s.episodes) for s in run.steered_sets(1)] == [2]
  assert [len(s.episodes) for s in run.steered_sets(1, only_successful=False)] == [3]
  assert run.steered_sets(0) == [] and all(s.steered and s.source == 0 for s in run.steered_sets(1))
