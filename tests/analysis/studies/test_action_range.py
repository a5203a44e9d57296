"""The round-0 action-range study's distances and its bucketed, paired table."""

import numpy as np

from soe_jax.analysis.studies import action_range


def test_distance_outside_is_zero_inside_and_euclidean_beyond_a_corner():
  lo, hi = np.array([-0.01, -0.01, 0.8]), np.array([0.02, 0.03, 1.0])
  xy = np.array([[0.0, 0.0], [0.025, 0.0], [-0.04, 0.07]])
  np.testing.assert_allclose(action_range.distance_outside(xy, lo, hi), [0.0, 0.005, np.hypot(0.03, 0.04)])


def test_table_buckets_states_by_distance_and_pairs_the_two_round0s():
  seed = dict(
    distance_mm=[0, 0, 2, 7, 12, 15],
    round0={"demonstrations": [1, 1, 1, 0, 0, 0], "workspace": [1, 0, 1, 1, 1, 1]},
  )
  table = action_range.ActionRange.table([("lift", dict(seeds=[seed]))])
  rows = {line.split(" | ")[0].strip("| "): line.split(" | ") for line in table.splitlines()[2:]}
  assert rows["inside"][1:5] == ["2", "100.0%", "50.0%", "0 / 1"]
  assert rows["< 5 mm"][1:5] == ["1", "100.0%", "100.0%", "0 / 0"]
  assert rows["5-10 mm"][1:5] == ["1", "0.0%", "100.0%", "1 / 0"]
  assert rows[">= 10 mm"][1:5] == ["2", "0.0%", "100.0%", "2 / 0"]
  assert rows["all"][1:5] == ["6", "50.0%", "83.3%", "3 / 1"]
