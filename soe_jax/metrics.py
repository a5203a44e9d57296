"""The paper's metrics as pure functions on rollout outputs (DESIGN.md, "Metrics").

- Success rate with its episode count and a 95% Wilson interval.
- Pass@k: the fraction of start states with at least one success among their k tries.
- Rollouts: per start state, tries up to and including the first success (k if none); the sum over
  start states (the paper's "rollout num") and the mean per start state. Tries may run in parallel;
  the count is what a robot doing them one after another would spend.
- Average jerk: per episode, the mean over its third differences of ||d^3 p / dt^3|| of the measured
  end-effector position at the control rate (dt = 0.05 s), over the whole episode (to success or the
  episode length); then the mean over episodes.
- Relative improvement (after - before) / before, always with the absolute difference beside it (and
  alone when before is 0).
- Paired comparisons on the same start states: states gained and lost with McNemar's exact p-value
  (one training seed), and across seeds the Cochran-Mantel-Haenszel test stratified over (seed, state)
  pairs with the spread of the per-seed differences.
"""

from __future__ import annotations

import math

import numpy as np

CONTROL_DT = 0.05


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
  """95% Wilson score interval for a binomial proportion (0, 1) when n is 0."""
  if n == 0:
    return 0.0, 1.0
  p = successes / n
  denom = 1 + z * z / n
  centre = (p + z * z / (2 * n)) / denom
  half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
  return max(0.0, round(centre - half, 12)), min(1.0, round(centre + half, 12))


def success_rate(success) -> dict:
  """success (N,) bool -> {rate, num_episodes, wilson_low, wilson_high}."""
  s = np.asarray(success, bool).ravel()
  low, high = wilson_interval(int(s.sum()), s.size)
  return dict(rate=float(s.mean()) if s.size else 0.0, num_episodes=int(s.size), wilson_low=low, wilson_high=high)


def pass_at_k(success) -> float:
  """success (S, k): tries per start state -> fraction of start states with any success."""
  s = np.asarray(success, bool)
  return float(s.any(axis=1).mean())


def rollouts(success) -> dict:
  """success (S, k) -> {sum, mean, per_state (S,)}: tries up to and including the first success, k if none."""
  s = np.asarray(success, bool)
  k = s.shape[1]
  first = np.where(s.any(axis=1), s.argmax(axis=1) + 1, k)
  return dict(sum=int(first.sum()), mean=float(first.mean()), per_state=first)


def episode_jerk(positions, length: int | None = None, dt: float = CONTROL_DT) -> float:
  """positions (T, 3), or (T, R, 3) for R robots (padded beyond `length`) -> mean ||third difference||
  / dt^3 over the episode (and the robots)."""
  p = np.asarray(positions, np.float64)
  p = p[: length if length is not None else p.shape[0]]
  if p.shape[0] < 4:
    return 0.0
  third = np.diff(p, n=3, axis=0) / dt**3
  return float(np.linalg.norm(third, axis=-1).mean())


def average_jerk(positions, lengths, dt: float = CONTROL_DT) -> float:
  """positions (N, T, [R,] 3), lengths (N,) -> the mean over episodes of each episode's jerk."""
  return float(np.mean([episode_jerk(p, int(n), dt) for p, n in zip(positions, lengths)]))


def relative_improvement(before: float, after: float) -> dict:
  """{absolute, relative}; relative is None when `before` is 0 (only the absolute difference is shown)."""
  return dict(absolute=after - before, relative=None if before == 0 else (after - before) / before)


def rollout_summary(out: dict, tries: int, normalizer=None, control_hz: float = 1 / CONTROL_DT) -> dict:
  """A rollout phase's numbers from `rollout.rollout`'s output, with `tries` adjacent tries per start
  state: success rate and Wilson interval, jerk (at `control_hz`, the spec's: jerk at 10 Hz is not
  jerk at 20 Hz), mean length, (k > 1) Pass@k and rollouts, and with
  the policy's `normalizer` the fraction of its observation features outside [-1, 1] over the frames
  it acted on (`obs_out_of_range`)."""
  sr = success_rate(out["success"])
  rec = dict(
    success_rate=sr["rate"],
    num_rollouts=sr["num_episodes"],
    wilson_low=sr["wilson_low"],
    wilson_high=sr["wilson_high"],
    jerk=average_jerk(out["eef_pos"], out["length"] + 1, 1.0 / control_hz),
    mean_length=float(out["length"].mean()),
  )
  if normalizer is not None:
    seen = out.get("policy_obs", out["obs"])  # what the policy read (its keys), else every policy key
    acted = np.arange(seen.shape[1]) < np.asarray(out["length"])[:, None]
    rec["obs_out_of_range"] = float(normalizer.out_of_range_fraction(seen, acted))
  if tries > 1:
    s = out["success"].reshape(-1, tries)
    r = rollouts(s)
    rec.update(k=tries, pass_at_k=pass_at_k(s), rollouts=r["sum"], rollouts_mean=r["mean"])
  return rec


def sign_test_p(up: int, down: int) -> float:
  """The exact two-sided sign test: how likely a split at least as uneven as `up` against `down` is
  when each of the `up + down` differing pairs goes either way with probability 1/2 (McNemar's exact
  test when the pairs are gained and lost states)."""
  n, k = up + down, min(up, down)
  return 1.0 if n == 0 else min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n)


def paired_comparison(before, after, z: float = 1.959963984540054) -> dict:
  """Per-state outcomes (N,) of two evaluations on the same start states -> states gained and lost,
  McNemar's exact two-sided p-value (binomial on the discordant pairs), and the difference in success
  rate with its Wald interval for paired proportions (se^2 = ((g + l) / N - ((g - l) / N)^2) / N)."""
  before, after = np.asarray(before, bool), np.asarray(after, bool)
  gained, lost = int((after & ~before).sum()), int((before & ~after).sum())
  n, p = gained + lost, sign_test_p(gained, lost)
  states = len(before)
  diff = (gained - lost) / states
  se = math.sqrt(max(0.0, (n / states - diff**2) / states))
  return dict(gained=gained, lost=lost, p_value=p, difference=diff, low=diff - z * se, high=diff + z * se)


def convergence(before, after, curve_rates, max_change: float = 0.03, max_step: float = 0.05) -> dict:
  """Is a fit converged? `before`, `after`: per-state outcomes of the fitted policy and of the same fit
  continued (more steps on the same data), on the same states and sampling keys; `curve_rates`: the
  success rates of its in-fit evaluations. Converged: continuing changes success by less than
  `max_change`, and the last two in-fit evaluations are within `max_step` of each other."""
  c = paired_comparison(before, after)
  last_two = abs(curve_rates[-1] - curve_rates[-2]) if len(curve_rates) >= 2 else None
  ok = abs(c["difference"]) < max_change and last_two is not None and last_two <= max_step
  return dict(c, last_two_change=last_two, converged=bool(ok))


def cmh_test(tables) -> dict:
  """Cochran-Mantel-Haenszel test of K 2x2 tables (K, 2, 2), rows the two arms and columns success and
  failure: {statistic, p_value (chi-square, 1 df, no continuity correction), odds_ratio (Mantel-
  Haenszel's common odds ratio; None when undefined)}. Strata of fewer than 2 observations carry no
  information and are left out. On matched pairs (each stratum one state under both arms) the
  statistic is McNemar's (gained - lost)^2 / (gained + lost)."""
  t = np.asarray(tables, np.float64).reshape(-1, 2, 2)
  n = t.sum(axis=(1, 2))
  t, n = t[n > 1], n[n > 1]
  a, b, c, d = t[:, 0, 0], t[:, 0, 1], t[:, 1, 0], t[:, 1, 1]
  expected = (a + b) * (a + c) / n
  var = (a + b) * (c + d) * (a + c) * (b + d) / (n**2 * (n - 1))
  stat = float((a - expected).sum() ** 2 / var.sum()) if var.sum() > 0 else 0.0
  num, den = float((a * d / n).sum()), float((b * c / n).sum())
  return dict(statistic=stat, p_value=math.erfc(math.sqrt(stat / 2)), odds_ratio=num / den if den > 0 else None)


def pooled_comparison(pairs) -> dict:
  """Per training seed, the per-state outcomes of a reference and of a method on the same states:
  [(reference (N_s,), method (N_s,)), ...] -> states gained and lost over all seeds, the difference in
  success rate per seed with its mean and sample standard deviation over seeds, and the CMH test over the
  (seed, state) strata (`cmh_test`; its p-value is the pooled paired test)."""
  per_seed = [paired_comparison(ref, m) for ref, m in pairs]
  tables = [
    [[m, 1 - m], [r, 1 - r]] for ref, mine in pairs for r, m in zip(np.asarray(ref, int), np.asarray(mine, int))
  ]
  test = cmh_test(tables)
  diffs = [c["difference"] for c in per_seed]
  return dict(
    gained=sum(c["gained"] for c in per_seed),
    lost=sum(c["lost"] for c in per_seed),
    differences=diffs,
    difference_mean=float(np.mean(diffs)),
    difference_std=float(np.std(diffs, ddof=1)) if len(diffs) > 1 else 0.0,
    p_value=test["p_value"],
    statistic=test["statistic"],
    seed_p_values=[c["p_value"] for c in per_seed],
  )
