"""Metrics on hand-made outcome tables and paths."""

import numpy as np
import pytest

from soe_jax import metrics


def test_pass_at_k_and_rollouts_on_outcome_tables():
  table = np.array(
    [
      [0, 0, 1, 0, 1],  # first success on try 3
      [1, 1, 1, 1, 1],  # on try 1
      [0, 0, 0, 0, 0],  # never: counts all 5 tries
      [0, 0, 0, 0, 1],
    ],
    bool,
  )
  assert metrics.pass_at_k(table) == 0.75
  r = metrics.rollouts(table)
  np.testing.assert_array_equal(r["per_state"], [3, 1, 5, 5])
  assert r["sum"] == 14 and r["mean"] == 3.5
  none, every = np.zeros((3, 5), bool), np.ones((3, 5), bool)
  assert metrics.pass_at_k(none) == 0.0 and metrics.rollouts(none)["sum"] == 15
  assert metrics.pass_at_k(every) == 1.0 and metrics.rollouts(every)["sum"] == 3


def test_success_rate_reports_count_and_wilson_interval():
  r = metrics.success_rate([True] * 8 + [False] * 2)
  assert r["rate"] == 0.8 and r["num_episodes"] == 10
  np.testing.assert_allclose([r["wilson_low"], r["wilson_high"]], [0.4902, 0.9433], atol=1e-4)
  assert metrics.success_rate([False] * 5)["wilson_low"] == 0.0
  assert metrics.success_rate([True] * 5)["wilson_high"] == 1.0


def test_wilson_interval_matches_scipys():
  from scipy import stats

  for k, n in [(0, 1), (1, 1), (3, 10), (57, 200), (199, 200), (500, 1000)]:
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    np.testing.assert_allclose(metrics.wilson_interval(k, n), (ci.low, ci.high), atol=1e-9)


def test_jerk_is_zero_for_a_quadratic_and_exact_for_a_cubic():
  t = np.arange(40) * metrics.CONTROL_DT
  quad = np.stack([3 * t**2 - t, 0.5 * t**2, np.ones_like(t)], -1)
  assert abs(metrics.episode_jerk(quad)) < 1e-6
  cubic = np.stack([2 * t**3, -(t**3), t**2], -1)  # third derivative (12, -6, 0): norm sqrt(180)
  np.testing.assert_allclose(metrics.episode_jerk(cubic), np.sqrt(180.0), rtol=1e-6)
  # Padding past an episode's length is ignored; episodes are averaged.
  padded = np.concatenate([cubic, np.full((10, 3), 99.0)])
  np.testing.assert_allclose(
    metrics.average_jerk(np.stack([padded, np.concatenate([quad, quad[:10]])]), [40, 40]), np.sqrt(180.0) / 2, rtol=1e-6
  )
  # Two arms: each arm's jerk, averaged over the arms.
  np.testing.assert_allclose(metrics.episode_jerk(np.stack([cubic, quad], 1)), np.sqrt(180.0) / 2, rtol=1e-6)
  # At the spec's control rate: the same cubic sampled at 10 Hz is the same physical jerk.
  t10 = np.arange(40) * 0.1
  out = dict(
    success=np.ones(1, bool), eef_pos=np.stack([2 * t10**3, -(t10**3), t10**2], -1)[None], length=np.array([39])
  )
  np.testing.assert_allclose(metrics.rollout_summary(out, 1, control_hz=10.0)["jerk"], np.sqrt(180.0), rtol=1e-6)
  assert metrics.rollout_summary(out, 1)["jerk"] == pytest.approx(8 * np.sqrt(180.0))  # read at 20 Hz: 8x too high


def test_relative_improvement_keeps_the_absolute_difference():
  r = metrics.relative_improvement(0.4, 0.6)
  np.testing.assert_allclose([r["absolute"], r["relative"]], [0.2, 0.5])
  r = metrics.relative_improvement(0.0, 0.3)
  assert r["relative"] is None and r["absolute"] == 0.3


def test_episode_selection_rules():
  from soe_jax.experiment.select import select

  s = np.array([[0, 1, 1, 0, 0], [0, 0, 0, 0, 0], [1, 1, 1, 1, 0], [1, 0, 0, 0, 1]], bool)
  length = np.array([[9, 50, 30, 9, 9], [9] * 5, [40, 20, 20, 60, 5], [70, 9, 9, 9, 45]])
  np.testing.assert_array_equal(select(s, length), [[0, 1, 0, 0, 0], [0] * 5, [1, 0, 0, 0, 0], [1, 0, 0, 0, 0]])
  # the shortest success, the first of equal ones; a failure's length does not count
  np.testing.assert_array_equal(
    select(s, length, "shortest_success"), [[0, 0, 1, 0, 0], [0] * 5, [0, 1, 0, 0, 0], [0, 0, 0, 0, 1]]
  )
  np.testing.assert_array_equal(select(s, length, "all_successes"), s)
  # SIME's train_0.5: states with success rate 0.4 (rows 0 and 3) keep all their successes; 0.8 drops.
  np.testing.assert_array_equal(select(s, length, "sime"), [[0, 1, 1, 0, 0], [0] * 5, [0] * 5, [1, 0, 0, 0, 1]])
  # a cap of 45 actions: longer successes count as failures (row 2 falls to 0.6, row 3 to 0.2)
  np.testing.assert_array_equal(
    select(s, length, "first_success", max_length=45), [[0, 0, 1, 0, 0], [0] * 5, [1, 0, 0, 0, 0], [0, 0, 0, 0, 1]]
  )
  np.testing.assert_array_equal(
    select(s, length, "sime", max_length=45), [[0, 0, 1, 0, 0], [0] * 5, [0] * 5, [0, 0, 0, 0, 1]]
  )
  with pytest.raises(ValueError, match="known selections: all_successes, first_success, shortest_success, sime"):
    select(s, length, "best")


def test_paired_comparison_counts_gains_losses_and_mcnemars_p():
  """A paired comparison counts gains and losses, with McNemar's exact p-value."""
  before = np.array([1, 1, 0, 0, 0, 0, 0, 0, 0, 0])
  after = np.array([1, 0, 1, 1, 1, 1, 1, 1, 0, 0])
  c = metrics.paired_comparison(before, after)
  assert (c["gained"], c["lost"]) == (6, 1)
  assert abs(c["p_value"] - 2 * (1 + 7) / 2**7) < 1e-12  # 0.125
  assert abs(c["difference"] - 0.5) < 1e-12
  # Wald interval of a paired difference: se^2 = ((7 / 10) - 0.5^2) / 10
  assert abs(c["high"] - c["difference"] - 1.959963984540054 * np.sqrt(0.045)) < 1e-12
  same = metrics.paired_comparison(before, before)
  assert (same["gained"], same["lost"], same["p_value"], same["low"], same["high"]) == (0, 0, 1.0, 0.0, 0.0)


def test_convergence_needs_a_small_paired_change_and_flat_curve():
  rng = np.random.default_rng(0)
  before = rng.random(400) < 0.7
  after = before.copy()
  after[:8] = ~after[:8]  # 8 of 400 states change: at most 2 points either way
  flat, rising = [0.60, 0.70, 0.72], [0.50, 0.60, 0.70]
  check = metrics.convergence(before, after, flat)
  assert check["converged"] and abs(check["difference"]) <= 0.02 and check["low"] < check["difference"] < check["high"]
  assert not metrics.convergence(before, after, rising)["converged"]  # the last two 10 points apart
  assert not metrics.convergence(before, after, [0.7])["converged"]  # one point is no curve
  better = before.copy()
  better[~before] = True  # every failure becomes a success: far more than 3 points
  assert not metrics.convergence(before, better, flat)["converged"]


def test_cmh_matches_hand_computed_strata_and_mcnemar_on_pairs():
  """CMH on hand-computed strata; on matched pairs it is McNemar's test."""
  # Two strata, rows the arms, columns success / failure; by hand: sum(a - E) = 2.5 + 2, summed
  # variance 15^4 / (30^2 * 29) + 10 * 10 * 12 * 8 / (20^2 * 19) = 3.2028, statistic 6.3226,
  # p = P(chi2_1 > 6.3226) = 0.01192; MH odds ratio (100/30 + 48/20) / (25/30 + 8/20) = 4.6486.
  t = metrics.cmh_test([[[10, 5], [5, 10]], [[8, 2], [4, 6]]])
  assert t["statistic"] == pytest.approx(6.3226, abs=1e-4)
  assert t["p_value"] == pytest.approx(0.01192, abs=1e-5)
  assert t["odds_ratio"] == pytest.approx(4.6486, abs=1e-4)
  assert metrics.cmh_test([[[3, 0], [3, 0]]])["p_value"] == 1.0  # no variance: no evidence
  # Seeds x states as strata: 4 gained and 1 lost over two seeds -> McNemar's chi-square 9 / 5.
  c = metrics.pooled_comparison([([1, 0, 0, 1], [1, 1, 1, 0]), ([0, 0, 1], [1, 1, 1])])
  assert (c["gained"], c["lost"]) == (4, 1)
  assert c["statistic"] == pytest.approx(1.8) and c["p_value"] == pytest.approx(0.17971, abs=1e-5)
  assert c["differences"] == pytest.approx([0.25, 2 / 3])
  assert c["difference_mean"] == pytest.approx(11 / 24) and c["difference_std"] == pytest.approx(0.294628, abs=1e-6)
  assert c["seed_p_values"] == pytest.approx([1.0, 0.5])  # McNemar's exact, per seed
