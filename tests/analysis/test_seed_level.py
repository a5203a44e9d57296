"""Seed-level inference: statsmodels' Hartung-Knapp interval, the moderated family, verdicts with known answers."""

import warnings

import numpy as np
import pytest
from scipy import stats

from soe_jax.analysis import seed_level as sl


def test_unmoderated_interval_equals_statsmodels_hartung_knapp():
  meta = pytest.importorskip("statsmodels.stats.meta_analysis")
  rng = np.random.default_rng(0)
  checked = {"hk": 0, "floor": 0}
  for _ in range(40):
    k = int(rng.integers(3, 7))
    d, v = rng.normal(0.03, rng.uniform(0.01, 0.08), k), rng.uniform(3e-4, 3e-3, k)
    ours = sl.combine(sl.Effects(d, v))
    with warnings.catch_warnings():
      warnings.simplefilter("ignore")
      theirs = meta.combine_effects(d, v, method_re="iterated", use_t=True)
      frame = theirs.summary_frame()
    assert sl.tau2_pm([sl.Effects(d, v)]) == pytest.approx(theirs.tau2, rel=1e-3, abs=1e-8)  # (statsmodels: to 1e-5)
    # Hartung-Knapp where its scale is at least 1; the modification keeps the random-effects interval below it
    row = "random effect wls" if theirs.scale_hksj_re >= 1 else "random effect"
    checked["hk" if row.endswith("wls") else "floor"] += 1
    assert ours.estimate == pytest.approx(frame.loc[row, "eff"], abs=1e-6)
    assert ours.low == pytest.approx(frame.loc[row, "ci_low"], abs=1e-5)
    assert ours.high == pytest.approx(frame.loc[row, "ci_upp"], abs=1e-5)
  assert checked["hk"] > 5 and checked["floor"] > 5  # both branches were exercised


def test_modified_interval_never_narrower_than_the_fixed_effect_one():
  d, v = np.array([0.05, 0.05, 0.05]), np.array([1e-3, 1e-3, 1e-3])  # identical seeds: HK's scale is 0
  t = sl.combine(sl.Effects(d, v))
  assert t.se == pytest.approx((1 / (3 / 1e-3)) ** 0.5)


def _layout(*columns):
  """(seeds, fits) success rates of hand-made fits, per column a rate per seed."""
  return np.array(columns, float).T


def test_large_effect_on_every_seed_is_reproduced():
  y = _layout((0.60, 0.62, 0.58), (0.80, 0.83, 0.79), (0.61, 0.60, 0.60))  # control, arm, another arm
  (test,) = sl.moderated(y, [(1, 0)])
  assert test.estimate == pytest.approx(0.2067, abs=1e-4) and test.df == 4
  assert sl.verdict(test, tested=0.1) == sl.REPRODUCED


def test_effects_that_cancel_across_seeds_are_inconclusive():
  y = _layout((0.60, 0.60, 0.60), (0.70, 0.50, 0.62), (0.58, 0.64, 0.57))
  (test,) = sl.moderated(y, [(1, 0)])
  assert test.p_value > 0.05 and test.low < 0 < test.high < 0.1 + 0.2
  assert sl.verdict(test, tested=0.5) == sl.CONTRADICTED  # the interval excludes a large enough number
  assert sl.verdict(test, tested=0.1) == sl.INCONCLUSIVE


def test_an_interval_below_the_tested_number_contradicts():
  y = _layout((0.60, 0.61, 0.59), (0.57, 0.56, 0.58), (0.60, 0.62, 0.58))
  (test,) = sl.moderated(y, [(1, 0)])
  assert test.high < 0.1
  assert sl.verdict(test, tested=0.1) == sl.CONTRADICTED
  assert sl.verdict(test, tested=-0.2) == sl.INCONCLUSIVE  # a number the interval does not exclude
  # a claim of "fewer": contradicted when the whole interval is above the number
  assert sl.verdict(test._replace(low=0.01, high=0.05, estimate=0.03), tested=0.0, direction=-1) == sl.CONTRADICTED


def test_two_seeds_are_an_anecdote():
  (test,) = sl.moderated(_layout((0.6, 0.6), (0.9, 0.85), (0.6, 0.62)), [(1, 0)])
  assert sl.verdict(test, tested=0.1) == sl.ANECDOTE


def test_the_moderated_variance_is_the_two_way_residual_of_the_shared_fits():
  """A contrast's variance is 2 MSE / k of the seeds x fits table, MSE with (k - 1)(F - 1) df: the
  one-sample t-test when two fits are all there is, a pooled estimate with more fits."""
  rng = np.random.default_rng(0)
  y = rng.uniform(0.4, 0.8, (4, 2))
  (test,) = sl.moderated(y, [(1, 0)])
  reference = stats.ttest_1samp(y[:, 1] - y[:, 0], 0.0)
  assert test.df == 3 and test.p_value == pytest.approx(reference.pvalue)
  y = rng.uniform(0.4, 0.8, (3, 6))
  mse, df = sl.residual_variance(y)
  res = y - y.mean(0) - y.mean(1)[:, None] + y.mean()
  assert df == 10 and mse == pytest.approx((res**2).sum() / 10)
  (test,) = sl.moderated(y, [(2, 0)])
  assert test.se == pytest.approx((2 * mse / 3) ** 0.5) and test.sd == pytest.approx((2 * mse) ** 0.5)


def test_homogeneity_checks_the_family():
  noisy = sl.Effects(np.array([0.10, -0.05, 0.02]), np.full(3, 1e-3))
  quiet = sl.Effects(np.array([0.03, 0.02, 0.04]), np.full(3, 1e-3))
  h = sl.homogeneity([noisy, quiet])
  assert h["df"] == 4 and h["comparisons"] == 2 and h["tau2"] == pytest.approx(sl.tau2_pm([noisy, quiet]))
  assert 0 <= h["worst_p"] <= 1 and h["p_value"] < 0.05  # the noisy comparison spreads beyond its within-seed noise


def test_seeds_needed_grows_with_the_seed_to_seed_spread():
  few = sl.seeds_needed(0.1, sd=0.05, fits=6)
  many = sl.seeds_needed(0.1, sd=0.15, fits=6)
  assert few is not None and many is not None and few < many
  assert sl.seeds_needed(0.001, sd=0.2, fits=6, most=10) is None
