"""The start states a run evaluates and explores from are the ones the committed runs used (typed
`jax.random.key`s give the bits `PRNGKey` gave), so new runs pair state by state with them."""

import jax
import numpy as np

from configs import lift
from soe_jax.envs.registry import make_env
from soe_jax.experiment import phases

# Lift `cpu,soe`, training seed 0, as `jax.random.PRNGKey` gave them: the reset keys of the first three
# evaluation and round-1 exploration start states, and the cube's position at each.
EVALUATION_KEYS = [[2043839838, 3369919191], [1817426458, 4273942588], [2205280080, 2575787326]]
EXPLORATION_KEYS = [[3276925600, 2751771740], [2215249346, 143550061], [3270805043, 4194985171]]
EVALUATION_CUBES = [[0.003386, -0.003758, 0.831], [-0.020978, 0.01761, 0.831], [0.012184, -0.027851, 0.831]]
EXPLORATION_CUBES = [[-0.007012, -0.007021, 0.831], [-0.018954, 0.00085, 0.831], [-0.011937, -0.02839, 0.831]]


def test_start_keys_are_the_committed_runs():
  config = lift.get_config("cpu,soe")
  evaluation = phases.evaluation_starts(config)
  exploration = phases.exploration_starts(config, 1)
  assert evaluation.shape == (config.eval.num_start_states,)
  assert exploration.shape == (config.explore.num_start_states * config.explore.tries,)
  np.testing.assert_array_equal(jax.random.key_data(evaluation[:3]), EVALUATION_KEYS)
  tries = config.explore.tries
  np.testing.assert_array_equal(jax.random.key_data(exploration[: 3 * tries : tries]), EXPLORATION_KEYS)
  assert (jax.random.key_data(exploration[:tries]) == np.asarray(EXPLORATION_KEYS[0])).all()  # tries adjacent


def test_start_states_are_the_committed_runs():
  config = lift.get_config("cpu,soe")
  env = make_env("lift", backend="mujoco")
  exploration = phases.exploration_starts(config, 1)[:: config.explore.tries]
  for keys, cubes in ((phases.evaluation_starts(config)[:3], EVALUATION_CUBES), (exploration[:3], EXPLORATION_CUBES)):
    got = [np.asarray(env.reset(k).obs["object"][:3]) for k in keys]
    np.testing.assert_allclose(got, cubes, atol=1e-6)
