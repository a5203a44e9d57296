"""The paper's four comparative claims, tested on a campaign's runs (`aggregate.rows`), one sentence each.

The training seed is the replicate (`seed_level`): each comparison is a paired difference per seed on
the seed's shared start states; verdicts rest on the moderated seed-level test, which pools the
seed-to-seed spread over the fits of the same task in the folder (a `Layout`: seeds x fits):
- success: a method's last round against the control's (fits: the control, its round 0 and every arm
  that shares that round 0, the oracle arms left out: `success_fits`);
- Pass@5: per exploration start state, whether any of its tries succeeded (fits: the exploring
  methods' per-seed Pass@5);
- rollouts: per exploration start state, tries up to the first success (fits: the exploring methods'
  per-seed means);
- jerk: each seed's mean exploration jerk; a paired t-test over seeds on its logarithm.
Each line prints the per-seed differences, the seed-level estimate with its 95% interval and p-value,
and beside it the pooled p-value over (seed, state) pairs (CMH, or the exact sign test for rollouts),
which treats the fits as fixed.

Verdicts (`seed_level.verdict`): reproduced (the paper's direction at seed-level p < 0.05),
contradicted (the interval excludes the tested number on the paper's side), inconclusive (with the
seeds that would detect the number at 80% power), or an anecdote (fewer than 3 seeds: no p-value).
The tested numbers: SOE's success gain is tested against the paper's smallest relative gain
of SOE alone, +19.1% of round 0 (its real-robot Table I; the paper gives no number for simulation in
its text), in points of the seeds' own round 0; the other claims have no magnitude in the paper's text
and are tested for their direction, against 0 (a ratio of 1 for jerk).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from soe_jax import metrics
from soe_jax.analysis import seed_level as sl

ALPHA = 0.05
# SOE alone's relative gains on the real robot (the paper's Table I: +19.1 / +33.9 / +38.0%): the smallest.
SOE_RELATIVE_GAIN = 0.191


class Claim(NamedTuple):
  """One claim tested: what the paper says, the verdict (reproduced, contradicted, inconclusive,
  anecdote, or not measured) and the numbers behind it; `str` is the sentence the tables print."""

  title: str
  verdict: str
  detail: str

  def __str__(self) -> str:
    if self.verdict == "not measured":
      return f"{self.title}: not measured ({self.detail})."
    return f"{self.title}: {self.verdict}; {self.detail}."


SUCCESS = "SOE raises success (paper, real robot: SOE alone +19.1% to +38.0% relative; DP can degrade)"
PASS = "Pass@5 ordered SOE > SIME > DP"
ROLLOUTS = "SOE needs the fewest rollouts"
JERK = "SIME's jerk far above DP's and SOE's"


def _by_method(rows: list[dict], task: str) -> dict:
  return {r["method"]: r for r in rows if r["task"] == task and not r["variant"]}


def _explored(run: dict) -> np.ndarray | None:
  """(states, tries) exploration outcomes of round 1."""
  out = run["outcomes"]["explore"].get("1")
  return None if out is None else np.asarray(out, bool).reshape(-1, int(run["k"]))


def _seed_pairs(a: dict, b: dict, per_state) -> list[tuple]:
  """[(b's, a's) per-state values] for the seeds both methods ran (b the reference)."""
  runs_b = {r["seed"]: r for r in b["runs"]}
  pairs = []
  for r in a["runs"]:
    if r["seed"] in runs_b and (x := per_state(r)) is not None and (y := per_state(runs_b[r["seed"]])) is not None:
      pairs.append((y, x))
  return pairs


def combined(verdicts: list[str]) -> str:
  """A claim of several parts: contradicted if one part is, an anecdote if one is, reproduced if all
  are, inconclusive otherwise."""
  if sl.CONTRADICTED in verdicts:
    return sl.CONTRADICTED
  if sl.ANECDOTE in verdicts:
    return sl.ANECDOTE
  return sl.REPRODUCED if all(v == sl.REPRODUCED for v in verdicts) else sl.INCONCLUSIVE


def _num(x: float, scale: float, digits: int) -> str:
  return f"{scale * x:+.{digits}f}"


def describe(name: str, test: sl.Test, pooled_p: float | None, unit: str = "points", scale: float = 100,
             digits: int = 1) -> str:  # fmt: skip
  """'SOE against the control -3.0 points [-7.0, +0.9] (per seed -5.5, +1.0, -4.5; seed-level p = 0.12,
  10 df; pooled p = 0.10)'; fewer than 3 seeds: the per-seed differences alone (an anecdote has no
  p-value)."""
  per_seed = ", ".join(_num(x, scale, digits) for x in test.d)
  if test.seeds < sl.MIN_SEEDS or math.isnan(test.p_value):
    return f"{name} {_num(test.estimate, scale, digits)} {unit} (per seed {per_seed})"
  pooled = "" if pooled_p is None else f"; pooled p = {pooled_p:.2g}"
  return (
    f"{name} {_num(test.estimate, scale, digits)} {unit} [{_num(test.low, scale, digits)}, "
    f"{_num(test.high, scale, digits)}] (per seed {per_seed}; seed-level p = {test.p_value:.2g}, {test.df} df{pooled})"
  )


def needs(verdict: str, test: sl.Test, tested: float, direction: int, fits: int, scale: float = 100,
          unit: str = "points") -> str:  # fmt: skip
  """What an inconclusive verdict would need: '; 9 seeds would detect +14.2 points at 80% power' (the
  tested number; for a claim of direction alone, the estimate, where it lies in the paper's direction)."""
  if verdict != sl.INCONCLUSIVE:
    return ""
  effect = tested if tested != 0 else (test.estimate if direction * test.estimate > 0 else 0.0)
  if effect == 0:
    return "; the estimate lies against the paper's direction"
  n = sl.seeds_needed(effect, test.sd, fits)
  shown = f"{_num(effect, scale, 1 if scale == 100 else 2)} {unit}"
  return (
    f"; more than 100 seeds would be needed to detect {shown}"
    if n is None
    else (f"; {n} seeds would detect {shown} at 80% power")
  )


class Layout(NamedTuple):
  """A family of fits of one task: their names and the (seeds, fits) table of per-seed summaries."""

  names: list[str]
  seeds: list
  y: np.ndarray

  def tests(self, contrasts: list[tuple[str, str]]) -> list[sl.Test]:
    """The moderated test of each (fit, reference) by name."""
    return sl.moderated(self.y, [(self.names.index(a), self.names.index(b)) for a, b in contrasts])


def layout(per_seed: dict[str, dict]) -> Layout:
  """{fit: {seed: summary}} -> the `Layout` over the seeds every fit has."""
  seeds = sorted(set.intersection(*(set(v) for v in per_seed.values()))) if per_seed else []
  names = list(per_seed)
  return Layout(names, seeds, np.array([[per_seed[n][s] for n in names] for s in seeds], float).reshape(len(seeds), -1))


def _rate(outcomes) -> float:
  return float(np.mean(np.asarray(outcomes, float)))


def success_fits(rows: list[dict], task: str, oracle: bool = False) -> dict[str, dict]:
  """The family of success on `task`: {fit: {seed: per-state outcomes}} for the control's last round,
  its round 0, and each arm's last round whose round 0 is the control's on every seed (the oracle arms,
  `expert_data`, only with `oracle`: near the ceiling their seed-to-seed spread is not the others')."""
  control = next((r for r in rows if r["task"] == task and r["method"] == "control" and not r["variant"]), None)
  if control is None:
    return {}
  base = {r["seed"]: r["outcomes"]["evaluate"]["0"] for r in control["runs"]}
  fits = {"control": {r["seed"]: r["outcomes"]["evaluate"][r["last"]] for r in control["runs"]}, "round 0": base}
  for r in rows:
    if r["task"] != task or r is control or r["method"].split("-")[0] == "control":
      continue
    if "expert_data" in r["method"] and not oracle:
      continue
    runs = [run for run in r["runs"] if run["last"] not in (None, "0")]
    if runs and all(run["seed"] in base and run["outcomes"]["evaluate"]["0"] == base[run["seed"]] for run in runs):
      name = f"{r['method']}{r['variant'] and ' (' + r['variant'] + ')'}"
      fits[name] = {run["seed"]: run["outcomes"]["evaluate"][run["last"]] for run in runs}
  return fits


def rates(fits: dict[str, dict]) -> dict[str, dict]:
  """{fit: {seed: per-state outcomes}} -> {fit: {seed: success rate}}."""
  return {name: {seed: _rate(o) for seed, o in by_seed.items()} for name, by_seed in fits.items()}


def against_reference(fits: dict[str, dict], reference: str = "control") -> dict[str, sl.Effects]:
  """Each other fit against `reference` on their common seeds: {fit: its per-seed `Effects`}."""
  ref = fits[reference]
  return {
    name: sl.effects([(ref[seed], by_seed[seed]) for seed in sorted(by_seed) if seed in ref])
    for name, by_seed in fits.items()
    if name != reference
  }


def tested_gain(lay: Layout) -> tuple[float, float]:
  """The success family's round 0 (its mean over seeds) and the gain SOE's claim is tested against, in
  points: `SOE_RELATIVE_GAIN` of that round 0."""
  round0 = float(np.mean(lay.y[:, lay.names.index("round 0")]))
  return round0, SOE_RELATIVE_GAIN * round0


def success_claim(rows: list[dict], task: str) -> Claim:
  m = _by_method(rows, task)
  soe, dp = m.get("soe"), m.get("dp")
  fits = success_fits(rows, task)
  if soe is None or soe["comparisons"]["control"] is None or "soe" not in fits:
    return Claim(SUCCESS, "not measured", "no soe and control runs")
  lay = layout(rates(fits))
  test = lay.tests([("soe", "control")])[0]
  round0, tested = tested_gain(lay)
  verdict = sl.verdict(test, tested)
  detail = describe("SOE against the control", test, soe["comparisons"]["control"]["p_value"])
  detail += f"; tested against {_num(tested, 100, 1)} points (+19.1% of round 0's {100 * round0:.1f}%)"
  detail += needs(verdict, test, tested, 1, len(lay.names))
  if dp is not None and "dp" in fits:
    detail += "; " + describe("DP against the control", lay.tests([("dp", "control")])[0],
                              dp["comparisons"]["control"]["p_value"])  # fmt: skip
  return Claim(SUCCESS, verdict, detail)


def _pass_pairs(a: dict, b: dict):
  return _seed_pairs(a, b, lambda r: None if (e := _explored(r)) is None else e.any(axis=1))


def _rollouts(r: dict):
  return None if (e := _explored(r)) is None else metrics.rollouts(e)["per_state"]


# The exploring methods of a family of Pass@5 or rollouts.
EXPLORERS = ("dp", "sime", "soe", "soe_steer")


def _explore_layout(m: dict, per_state) -> Layout:
  """The exploring methods' per-seed means of a per-state exploration value (`per_state`)."""
  fits = {}
  for name in EXPLORERS:
    if name in m:
      values = {run["seed"]: float(np.mean(v)) for run in m[name]["runs"] if (v := per_state(run)) is not None}
      if values:
        fits[name] = values
  return layout(fits)


def pass_claim(rows: list[dict], task: str) -> Claim:
  m = _by_method(rows, task)
  if not all(k in m for k in ("soe", "sime", "dp")):
    return Claim(PASS, "not measured", "needs soe, sime and dp runs")
  lay = _explore_layout(m, lambda r: None if (e := _explored(r)) is None else e.any(axis=1))
  if not all(k in lay.names for k in ("soe", "sime", "dp")):
    return Claim(PASS, "not measured", "no per-state exploration outcomes")
  parts, verdicts = [], []
  for (a, b), name in ((("soe", "sime"), "SOE - SIME"), (("sime", "dp"), "SIME - DP")):
    test = lay.tests([(a, b)])[0]
    verdict = sl.verdict(test, 0.0)
    verdicts.append(verdict)
    pooled = metrics.pooled_comparison(_pass_pairs(m[a], m[b]))["p_value"]
    parts.append(describe(name, test, pooled) + needs(verdict, test, 0.0, 1, len(lay.names)))
  return Claim(PASS, combined(verdicts), "; ".join(parts))


def sign_test(a, b) -> dict:
  """Paired values: how often a < b and a > b, and the exact sign test's p-value on those."""
  a, b = np.asarray(a), np.asarray(b)
  fewer, more = int((a < b).sum()), int((a > b).sum())
  return dict(fewer=fewer, more=more, p_value=metrics.sign_test_p(fewer, more))


def rollouts_claim(rows: list[dict], task: str) -> Claim:
  m = _by_method(rows, task)
  others = [k for k in ("dp", "sime") if k in m]
  if "soe" not in m or not others:
    return Claim(ROLLOUTS, "not measured", "needs soe and dp or sime runs")
  lay = _explore_layout(m, _rollouts)
  if "soe" not in lay.names or not any(k in lay.names for k in others):
    return Claim(ROLLOUTS, "not measured", "no per-state exploration outcomes")
  parts, verdicts = [], []
  for k in [k for k in others if k in lay.names]:
    test = lay.tests([("soe", k)])[0]
    verdict = sl.verdict(test, 0.0, direction=-1)
    verdicts.append(verdict)
    pairs = _seed_pairs(m["soe"], m[k], _rollouts)
    t = sign_test(np.concatenate([x for _, x in pairs]), np.concatenate([y for y, _ in pairs]))
    text = describe(f"SOE - {k}", test, t["p_value"], "rollouts a state", scale=1, digits=2)
    text += f", fewer on {t['fewer']} start states, more on {t['more']}"
    parts.append(text + needs(verdict, test, 0.0, -1, len(lay.names), 1, "rollouts a state"))
  return Claim(ROLLOUTS, combined(verdicts), "; ".join(parts))


def log_ratio_test(a: list[float], b: list[float], alpha: float = ALPHA) -> dict:
  """Per-seed values of two methods: the geometric mean of a / b, the paired t-test's two-sided
  p-value on log(a / b) and its (1 - alpha) interval as ratios (None for fewer than 2 seeds)."""
  d = np.log(np.asarray(a, float)) - np.log(np.asarray(b, float))
  out = dict(ratio=float(math.exp(d.mean())), p_value=None, low=None, high=None, seeds=len(d))
  if len(d) > 1 and np.std(d) > 0:
    se = float(np.std(d, ddof=1) / math.sqrt(len(d)))
    crit = float(stats.t.ppf(1 - alpha / 2, len(d) - 1))
    out.update(p_value=float(stats.ttest_1samp(d, 0.0).pvalue), low=math.exp(d.mean() - crit * se),
               high=math.exp(d.mean() + crit * se))  # fmt: skip
  return out


def _ratio_verdict(t: dict) -> str:
  if t["seeds"] < sl.MIN_SEEDS:
    return sl.ANECDOTE
  if t["p_value"] is not None and t["ratio"] > 1 and t["p_value"] < ALPHA:
    return sl.REPRODUCED
  if t["high"] is not None and t["high"] < 1:
    return sl.CONTRADICTED
  return sl.INCONCLUSIVE


def jerk_claim(rows: list[dict], task: str) -> Claim:
  m = _by_method(rows, task)
  soe, sime, dp = m.get("soe"), m.get("sime"), m.get("dp")
  if not (soe and sime and dp):
    return Claim(JERK, "not measured", "needs soe, sime and dp runs")
  tests = {}
  for name, a, b in (("SIME / DP", sime, dp), ("SIME / SOE", sime, soe), ("SOE / DP", soe, dp)):
    pairs = _seed_pairs(a, b, lambda run: run.get("jerk"))
    tests[name] = log_ratio_test([x for _, x in pairs], [y for y, _ in pairs])

  def shown(name: str, t: dict) -> str:
    if t["seeds"] < sl.MIN_SEEDS or t["p_value"] is None:
      return f"{name} {t['ratio']:.2f}x"
    return f"{name} {t['ratio']:.2f}x [{t['low']:.2f}, {t['high']:.2f}] (t-test over seeds p = {t['p_value']:.2g})"

  text = ", ".join(shown(k, t) for k, t in tests.items())
  return Claim(JERK, combined([_ratio_verdict(tests[k]) for k in ("SIME / DP", "SIME / SOE")]), text)


def claims(rows: list[dict], task: str) -> list[Claim]:
  return [success_claim(rows, task), pass_claim(rows, task), rollouts_claim(rows, task), jerk_claim(rows, task)]
