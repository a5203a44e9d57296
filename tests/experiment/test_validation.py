"""Configs refused before anything is written (`validation`), also from the command line."""

import importlib.util
import os
import subprocess
import sys

import pytest

from configs import lift as lift_config
from configs import square as square_config
from soe_jax.experiment import loop
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime.errors import UserError

REFUSED = [
  ("env.task", "nope", "unknown task 'nope'; known tasks: can, lift, square, transport"),
  ("policy.head.name", "transformer", "known heads: diffusion_unet, flow_unet, mlp"),
  ("explore.strategy.name", "noise", "known strategies: dp, expert, sime"),
  ("explore.strategy.name", "sime", "strategy 'sime' has no setting 'alpha'"),  # soe's settings
  ("rounds.select", "best", "known selections: all_successes, first_success"),
  ("rounds.refit", "warm", "known: continue, scratch"),
  ("rounds.refit_lr", -1e-4, r"rounds.refit_lr must be >= 0"),
  ("rounds.length_cap", -1.5, r"rounds.length_cap must be >= 0"),
  ("rounds.steered", "some", "known: successful, all"),
  ("rounds.refit_ema", "keep", "known: restart, carry"),
  ("policy.bypass.batch_fraction", 0.0, r"batch_fraction must be in \(0, 1\]"),
  ("data.num_demos", -2, "data.num_demos must be at least 1, got -2"),
  ("eval.num_start_states", -3, "eval.num_start_states must be at least 1"),
  ("explore.tries", -1, "explore.tries must be at least 1"),
  ("fit.num_steps", -5, "fit.num_steps must be at least 1"),
  ("rounds.num_rounds", -1, "rounds.num_rounds must be >= 0"),
  ("policy.n_action_steps", 20, r"n_action_steps \(20\) must be at most"),
  ("data.hdf5_path", "broken.hdf5", "is not a readable HDF5 file"),
  ("data.hdf5_path", "absent.hdf5", "does not exist"),
]


@pytest.mark.parametrize("field, value, message", REFUSED, ids=[f"{f}={v}" for f, v, _ in REFUSED])
def test_a_refused_config_writes_nothing(tmp_path, field, value, message):
  (tmp_path / "broken.hdf5").write_text("not hdf5")
  config = lift_config.get_config("smoke")
  config.update_from_flattened_dict({field: str(tmp_path / value) if field == "data.hdf5_path" else value})
  with pytest.raises(UserError, match=message):
    loop.run(config, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_wandb_must_be_installed(tmp_path, monkeypatch):
  logged = lift_config.get_config("smoke,soe")
  logged.log.wandb = True
  find_spec = importlib.util.find_spec
  monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "wandb" else find_spec(name, *a))
  with pytest.raises(UserError, match=r"log.wandb needs wandb, which is not installed: pip install -e '.\[wandb\]'"):
    loop.run(logged, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_another_tasks_demonstrations_are_refused(smoke_run, tmp_path):
  """A demonstration file's observations must have the task's keys and sizes."""
  _, config, workdir, _ = smoke_run
  square = square_config.get_config("smoke")
  square.data.hdf5_path = RunDir(workdir, config).demos_path  # lift's: a 10-number object vector
  with pytest.raises(UserError, match=r"obs 'object' has shape \(\d+, 10\), the task 'square' needs \(T, 14\)"):
    loop.run(square, str(tmp_path / "run"), progress=False)
  assert not os.path.exists(tmp_path / "run")


def test_command_line_error_is_one_line_exit_2(tmp_path):
  """The command line reports a refused config on one line and exits with status 2."""
  workdir = tmp_path / "run"
  bad = ["--config=configs/lift.py:smoke", "--config.data.num_demos=-2", f"--workdir={workdir}"]
  proc = subprocess.run([sys.executable, "-m", "soe_jax.main", *bad], capture_output=True, text=True, timeout=300)
  assert proc.returncode == 2
  assert proc.stderr.strip() == "error: data.num_demos must be at least 1, got -2"
  assert not workdir.exists() and "Failed to import warp" not in proc.stdout
