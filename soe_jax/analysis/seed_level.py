"""Seed-level inference: the training seed is the replicate.

A pooled test over (seed, state) pairs (`metrics.pooled_comparison`'s CMH) measures evaluation noise
for fixed fits; fitting again moves a seed's difference by more than that. Here each training seed
gives one paired difference of an arm and its reference on their shared start states (`paired`), and
the seeds combine in two ways:

- unmoderated (`combine`), one comparison on its own seeds: a random-effects mean with Paule and
  Mandel's iterated between-seed variance tau^2 (statsmodels' `combine_effects(method_re="iterated")`)
  and the Hartung-Knapp variance, modified so that it is never below the random-effects variance
  1 / sum(w) (never narrower than the fixed-effect interval either), with a t interval of k - 1
  degrees of freedom for k seeds: at 3 seeds, 2;
- moderated (`moderated`), what verdicts rest on: the comparisons of one task and protocol share
  their fits (every arm is compared with the same control, the control with round 0), so their
  seed-to-seed variance is pooled as the residual mean square of the seeds x fits table of per-seed
  summaries (success rate, Pass@5, mean rollouts: two-way, seeds as blocks); a comparison of two fits
  is the mean of its per-seed differences with variance 2 MSE / k and a t interval of (k - 1)(F - 1)
  degrees of freedom for F fits, the sum of k - 1 over the F - 1 comparisons with the shared reference.
  Pooling assumes every fit varies from seed to seed alike; `homogeneity` checks it with Cochran's Q
  per comparison at the pooled tau^2. (The differences against a shared control are not independent:
  each holds the control's own fit, so pooling their spreads around their own means would count the
  control's share once per arm; the two-way table counts it once. The calibration study,
  `studies/calibrate.py`, measures the test's false positives.)

Verdicts (`verdict`) rest on the moderated test; `seeds_needed` gives the training seeds that would
detect a tested number at 80% power under the family's seed-to-seed variance.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import optimize, stats

ALPHA = 0.05
POWER = 0.8


class Effects(NamedTuple):
  """One comparison's per-seed differences `d` (arm - reference) and their within-seed variances `v`."""

  d: np.ndarray
  v: np.ndarray


def paired(reference, arm) -> tuple[float, float]:
  """Per-state outcomes (N,) of a reference and an arm on the same states -> the difference in success
  rate (g - l) / N and its within-seed variance ((g + l) / N - d^2) / N (the paired-proportions Wald
  variance, McNemar's), at least 1 / N^2 so that a seed with no discordant state keeps a finite weight."""
  reference, arm = np.asarray(reference, bool), np.asarray(arm, bool)
  n = len(reference)
  gained, lost = int((arm & ~reference).sum()), int((reference & ~arm).sum())
  d = (gained - lost) / n
  return d, max(((gained + lost) / n - d * d) / n, 1.0 / n**2)


def effects(pairs) -> Effects:
  """[(reference, arm) per-state outcomes per seed] -> their `Effects` (`paired`)."""
  got = [paired(ref, arm) for ref, arm in pairs]
  return Effects(np.array([d for d, _ in got], float), np.array([v for _, v in got], float))


def _scaled_residuals(family: list[Effects], tau2: float) -> float:
  """sum over comparisons and seeds of w (d - mu)^2, w = 1 / (v + tau2), mu each comparison's weighted mean."""
  total = 0.0
  for e in family:
    w = 1.0 / (e.v + tau2)
    mu = float((w * e.d).sum() / w.sum())
    total += float((w * (e.d - mu) ** 2).sum())
  return total


def _df(family: list[Effects]) -> int:
  return sum(len(e.d) - 1 for e in family)


def tau2_pm(family: list[Effects]) -> float:
  """Paule-Mandel's tau^2 common to a family of comparisons: the tau^2 >= 0 at which the scaled
  residuals equal their degrees of freedom (0 where they fall short of them at tau^2 = 0)."""
  df = _df(family)
  if df <= 0 or _scaled_residuals(family, 0.0) <= df:
    return 0.0
  spread = max(float(np.var(np.concatenate([e.d for e in family]))), 1e-12)
  hi = spread
  while _scaled_residuals(family, hi) > df:
    hi *= 4
  return float(optimize.brentq(lambda t: _scaled_residuals(family, t) - df, 0.0, hi, xtol=1e-14, rtol=1e-12))


class Test(NamedTuple):
  """A seed-level test of one comparison: the per-seed differences, the mean, its standard error, t
  interval and two-sided p-value, the degrees of freedom, and the standard deviation of one seed's
  difference that the test assumed (for `seeds_needed`)."""

  d: tuple[float, ...]
  estimate: float
  se: float
  low: float
  high: float
  p_value: float
  df: int
  sd: float

  @property
  def seeds(self) -> int:
    return len(self.d)


def _t_test(d, estimate: float, se: float, df: int, sd: float, alpha: float) -> Test:
  d = tuple(float(x) for x in d)
  if df <= 0 or math.isnan(se):
    return Test(d, estimate, se, math.nan, math.nan, math.nan, df, sd)
  if se == 0:  # no spread at all (hand-made data): the t-test's limit
    return Test(d, estimate, se, estimate, estimate, 0.0 if estimate else 1.0, df, sd)
  crit = float(stats.t.ppf(1 - alpha / 2, df))
  p = float(2 * stats.t.sf(abs(estimate) / se, df))
  return Test(d, estimate, se, estimate - crit * se, estimate + crit * se, p, df, sd)


def combine(e: Effects, alpha: float = ALPHA) -> Test:
  """The unmoderated seed-level test of one comparison: Paule-Mandel tau^2 on its own seeds and the
  modified Hartung-Knapp interval with k - 1 degrees of freedom."""
  tau2 = tau2_pm([e])
  df = len(e.d) - 1
  scale = _scaled_residuals([e], tau2) / df if df > 0 else 1.0
  w = 1.0 / (e.v + tau2)
  mu = float((w * e.d).sum() / w.sum())
  se = math.sqrt(max(1.0, scale) / float(w.sum()))
  return _t_test(e.d, mu, se, df, math.sqrt(tau2 + float(e.v.mean())), alpha)


def residual_variance(y: np.ndarray) -> tuple[np.ndarray, int]:
  """A (..., seeds, fits) table of per-seed summaries -> the two-way residual mean square (seeds as
  blocks; one per leading index) and its degrees of freedom (k - 1)(F - 1)."""
  y = np.asarray(y, float)
  k, f = y.shape[-2:]
  res = y - y.mean(-2, keepdims=True) - y.mean(-1, keepdims=True) + y.mean((-2, -1), keepdims=True)
  df = (k - 1) * (f - 1)
  return ((res**2).sum((-2, -1)) / df if df > 0 else np.full(y.shape[:-2], math.nan)), df


def moderated(y: np.ndarray, contrasts: list[tuple[int, int]], alpha: float = ALPHA) -> list[Test]:
  """The moderated test of each contrast (a, b) of a family of fits: `y` (seeds, fits) holds each fit's
  per-seed summary on the seed's shared states (every fit has every seed); a contrast is fit a against
  fit b, the mean of the per-seed differences with variance 2 MSE / k, t with (k - 1)(F - 1) df."""
  y = np.asarray(y, float)
  mse, df = residual_variance(y)
  mse, k = float(mse), y.shape[0]
  out = []
  for a, b in contrasts:
    d = y[:, a] - y[:, b]
    se, sd = (math.sqrt(2 * mse / k), math.sqrt(2 * mse)) if df > 0 else (math.nan, math.nan)
    out.append(_t_test(d, float(d.mean()), se, df, sd, alpha))
  return out


def homogeneity(comparisons: list[Effects]) -> dict:
  """The moderated test's assumption, checked: Cochran's Q of the whole family at tau^2 = 0 (is there
  between-seed variance beyond the within-seed one?), and each comparison's Q at the pooled tau^2
  against chi^2(k - 1) (is tau^2 the same for all?): the smallest p-value, Bonferroni-adjusted over the
  comparisons."""
  pooled = [e for e in comparisons if len(e.d) > 1]
  if not pooled:
    return dict(q=None, df=0, p_value=None, tau2=0.0, worst_p=None, comparisons=0)
  df, tau2 = _df(pooled), tau2_pm(pooled)
  q0 = _scaled_residuals(pooled, 0.0)
  each = [stats.chi2.sf(_scaled_residuals([e], tau2), len(e.d) - 1) for e in pooled]
  return dict(
    q=q0,
    df=df,
    p_value=float(stats.chi2.sf(q0, df)),
    tau2=tau2,
    worst_p=float(min(1.0, min(each) * len(each))),
    comparisons=len(pooled),
  )


def seeds_needed(effect: float, sd: float, fits: int = 2, power: float = POWER, alpha: float = ALPHA,
                 most: int = 100) -> int | None:  # fmt: skip
  """The training seeds at which the moderated test of a family of `fits` fits detects `effect` with
  `power`, one seed's difference varying with standard deviation `sd` (the t-test's degrees of freedom
  (n - 1)(fits - 1)); None if more than `most`."""
  if effect == 0 or not sd > 0:
    return None
  for n in range(2, most + 1):
    df = (n - 1) * (fits - 1)
    crit = stats.t.ppf(1 - alpha / 2, df)
    nc = abs(effect) / (sd / math.sqrt(n))
    if stats.nct.sf(crit, df, nc) + stats.nct.cdf(-crit, df, nc) >= power:
      return n
  return None


REPRODUCED, CONTRADICTED, INCONCLUSIVE, ANECDOTE = "reproduced", "contradicted", "inconclusive", "anecdote"
MIN_SEEDS = 3


def verdict(test: Test, tested: float | None, direction: int = 1, alpha: float = ALPHA) -> str:
  """Reproduced: the paper's `direction` (+1 or -1) at p < alpha; contradicted: the interval excludes
  the `tested` number on the paper's side (for a claim of "more", the whole interval below it; a claim
  without a magnitude is tested against 0); inconclusive otherwise; fewer than 3 seeds: an anecdote."""
  if test.seeds < MIN_SEEDS:
    return ANECDOTE
  if direction * test.estimate > 0 and test.p_value < alpha:
    return REPRODUCED
  nearest = test.high if direction > 0 else test.low  # the interval's end on the paper's side
  if tested is not None and direction * nearest < direction * tested:
    return CONTRADICTED
  return INCONCLUSIVE
