"""Training targets against the action box: outside the workspace is an error naming file, episode,
step and dimension; under the demonstrations' range the fraction clipped is reported."""

import numpy as np
import pytest

from soe_jax.data.episodes import EpisodeSet
from soe_jax.data.spec import PolicySpec
from soe_jax.envs import registry
from soe_jax.policies import normalizer
from soe_jax.runtime.errors import UserError
from soe_jax.train import action_box


def _setup():
  spec = PolicySpec.from_dict(registry.task_spec("lift", "absolute"))
  lo, hi = spec.action_bounds()
  inside = np.tile(np.r_[0.0, 0.0, 0.9, np.zeros(6), 1.0], (20, 1)).astype(np.float32)
  norm = normalizer.fit(np.zeros((20, 2)), inside, 0.1, action_box=(lo, hi))
  demos = inside.copy()
  demos[:, :3] += np.linspace(-0.01, 0.01, 20)[:, None]  # the demonstrations' range: +-1 cm
  old = normalizer.fit(np.zeros((20, 2)), demos, 0.1)
  outside = inside.copy()
  outside[7, 1] = hi[1] + 0.01  # step 7: y beyond the box
  sets = [EpisodeSet([{"actions": inside}], 0), EpisodeSet([{"actions": inside}, {"actions": outside}], 1)]
  return spec, norm, old, sets


def test_a_target_outside_the_workspace_box_is_an_error_naming_where():
  spec, norm, _, sets = _setup()
  with pytest.raises(UserError, match=r"round1\.hdf5: episode 1, step 7: action dimension 1 \(robot0 position\[1\]\)"):
    action_box.check(sets, norm, spec, "workspace", lambda s: f"round{s.source}.hdf5")
  assert action_box.check(sets[:1], norm, spec, "workspace", str) == 0.0


def test_the_demonstrations_range_clips_and_reports_the_fraction():
  spec, _, old, sets = _setup()
  # The demonstrations' range is +-1.2 cm about (0, 0, 0.9): of the 60 actions, only the one with y beyond
  # the workspace is outside it.
  assert action_box.check(sets, old, spec, "demonstrations", str) == pytest.approx(1 / 60)
