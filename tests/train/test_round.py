"""One fit for the simulator and the robot: the same episodes under the same settings give the same
parameters through the simulated run's fit phase and through `robot/`, round 0 and a continued re-fit
with windows aligned to decisions; and the robot's `cpu` preset takes the simulated one's bypass weight
and window rule."""

import json

import chex
import ml_collections
import numpy as np

from soe_jax.data.episodes import EpisodeSet
from soe_jax.envs.registry import make_env
from soe_jax.experiment import phases
from soe_jax.experiment.rundir import RunDir
from soe_jax.experts import collect
from soe_jax.robot import config as robot_config
from soe_jax.robot import run as robot_run
from soe_jax.runtime import configfile
from soe_jax.train import checkpoint, normalization
from tests.experiment import toy


def _robot_config(sim: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
  """A robot's config holding the simulated one's settings of the fit, field by field under the same
  names (a field the robot's schema lacks is a KeyError)."""
  c = robot_config.config("smoke")
  c.seed = sim.seed
  c.policy, c.fit = ml_collections.ConfigDict(sim.policy.to_dict()), ml_collections.ConfigDict(sim.fit.to_dict())
  for name in c.rounds:
    c.rounds[name] = sim.rounds[name]
  for name in c.data:
    c.data[name] = sim.data[name]
  return c


def test_the_simulated_and_the_robot_fit_give_the_same_parameters(tmp_path):
  sim = toy.get_config("smoke,soe")
  sim.rounds.update(aligned_windows=True, refit="continue", round0_dir=str(tmp_path / "round0"))
  with toy.registered():
    exp = phases.Experiment(sim, RunDir(str(tmp_path / "sim"), sim), progress=False)
    demos = collect.demonstrations(make_env(toy.NAME), 4, 1000, progress=False)
    norm = normalization.fit_normalizer(exp.policy, exp.spec, demos, sim.policy.action_range, 0.1)
    sets = [EpisodeSet(demos, 0)]
    fit0 = exp.fit_phase(0, sets, norm)
    # Round 1 adds episodes "collected by the policy" (windows aligned to its decisions).
    own = [dict(ep, columns={}) for ep in demos[:2]]
    fit1 = exp.fit_phase(1, [*sets, EpisodeSet(own, 1)], norm, fit0)

  robot = _robot_config(sim)
  workdir = str(tmp_path / "robot")
  record0 = robot_run._fit(robot, exp.spec, exp.policy, sets, 0, workdir, norm, None, False)
  state0 = checkpoint.load(f"{workdir}/rounds/0/ckpt").state
  record1 = robot_run._fit(robot, exp.spec, exp.policy, [*sets, EpisodeSet(own, 1)], 1, workdir, norm, state0, False)
  state1 = checkpoint.load(f"{workdir}/rounds/1/ckpt").state
  for fitted, state in ((fit0, state0), (fit1, state1)):
    chex.assert_trees_all_equal((fitted.params, fitted.ema_params), (state.params, state.ema_params))
  assert record1["steps"] == sim.rounds.refit_steps and record0["steps"] == sim.fit.num_steps
  assert record0["loss_curve"] == json.load(open(exp.dir.phase_path(0, "fit")))["loss_curve"]


def test_the_robot_cpu_preset_takes_the_simulated_bypass_weight_and_windows():
  for presets in ("cpu", "cpu,image"):
    sim = configfile.load(f"configs/lift.py:{presets},soe")
    robot = robot_config.config(presets)
    assert robot.policy.bypass.beta == sim.policy.bypass.beta == 1e-5
    assert robot.rounds.aligned_windows is sim.rounds.aligned_windows is True
    # The robot's re-fit fields are the simulated runs' (names and types).
    assert {k: type(v) for k, v in robot.rounds.items()} == {k: type(sim.rounds[k]) for k in robot.rounds}
  assert np.isclose(robot_config.config("").policy.bypass.beta, 1e-3)  # paper scale: the paper's
