"""The paper's four comparative claims, tested on a campaign's runs (`aggregate.rows`), one sentence each.

Reproduced means the paper's direction with a pooled p < 0.05 against the control, or against the
baseline the claim names. Every test pairs the methods of a training seed on the same start states:
- success: a method's last round against the control's (CMH over (seed, state) pairs);
- Pass@5: per exploration start state, whether any of its tries succeeded (CMH over (seed, state));
- rollouts: per exploration start state, tries up to the first success; the sign test over the
  (seed, state) pairs where two methods differ (exact binomial);
- jerk: each seed's mean exploration jerk; a paired t-test over seeds on its logarithm.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import stats

from soe_jax import metrics

ALPHA = 0.05


class Claim(NamedTuple):
  """One claim tested: what the paper says, the verdict ("reproduced", "not reproduced", "untested"
  or "not measured") and the numbers behind it; `str` is the sentence the tables print."""

  title: str
  verdict: str
  detail: str

  def __str__(self) -> str:
    if self.verdict == "not measured":
      return f"{self.title}: not measured ({self.detail})."
    return f"{self.title}: {self.verdict}; {self.detail}."


SUCCESS = "SOE raises success (paper: +19% to +62% relative, DP can degrade)"
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


def _verdict(ok: bool) -> str:
  return "reproduced" if ok else "not reproduced"


def success_claim(m: dict) -> Claim:
  soe, dp = m.get("soe"), m.get("dp")
  if soe is None or soe["comparisons"]["control"] is None:
    return Claim(SUCCESS, "not measured", "no soe and control runs")
  c, dp_c = soe["comparisons"]["control"], dp and dp["comparisons"]["control"]
  ok = c["difference_mean"] > 0 and c["p_value"] < ALPHA
  rel = [x for x in soe["per_seed"]["improvement_rel"] if x is not None]
  rel = f"{100 * np.mean(rel):+.1f}% relative to round 0" if rel else "relative to round 0 undefined (round 0 at 0%)"
  dp_text = ""
  if dp_c is not None:
    dp_text = f"; DP against the control {100 * dp_c['difference_mean']:+.1f} points (p = {dp_c['p_value']:.2g})"
  seeds = f"{c['seeds']} seed{'s' if c['seeds'] > 1 else ''}"
  detail = f"SOE against the control {100 * c['difference_mean']:+.1f} points (p = {c['p_value']:.2g}, {seeds}), {rel}"
  return Claim(SUCCESS, _verdict(ok), detail + dp_text)


def _pass_pairs(a: dict, b: dict):
  return _seed_pairs(a, b, lambda r: None if (e := _explored(r)) is None else e.any(axis=1))


def pass_claim(m: dict) -> Claim:
  soe, sime, dp = m.get("soe"), m.get("sime"), m.get("dp")
  if not (soe and sime and dp):
    return Claim(PASS, "not measured", "needs soe, sime and dp runs")
  parts, ok = [], True
  for hi, lo, name in ((soe, sime, "SOE - SIME"), (sime, dp, "SIME - DP")):
    c = metrics.pooled_comparison(_pass_pairs(hi, lo))
    ok &= c["difference_mean"] > 0 and c["p_value"] < ALPHA
    parts.append(f"{name} {100 * c['difference_mean']:+.1f} points (p = {c['p_value']:.2g})")
  return Claim(PASS, _verdict(ok), ", ".join(parts))


def sign_test(a, b) -> dict:
  """Paired values: how often a < b and a > b, and the exact sign test's p-value on those."""
  a, b = np.asarray(a), np.asarray(b)
  fewer, more = int((a < b).sum()), int((a > b).sum())
  return dict(fewer=fewer, more=more, p_value=metrics.sign_test_p(fewer, more))


def _rollouts(r: dict):
  return None if (e := _explored(r)) is None else metrics.rollouts(e)["per_state"]


def rollouts_claim(m: dict) -> Claim:
  soe = m.get("soe")
  others = [(k, m[k]) for k in ("dp", "sime") if k in m]
  if soe is None or not others:
    return Claim(ROLLOUTS, "not measured", "needs soe and dp or sime runs")
  parts, ok = [], True
  for name, other in others:
    pairs = _seed_pairs(soe, other, _rollouts)
    if not pairs:
      return Claim(ROLLOUTS, "not measured", "no per-state exploration outcomes")
    t = sign_test(np.concatenate([x for _, x in pairs]), np.concatenate([y for y, _ in pairs]))
    ok &= t["fewer"] > t["more"] and t["p_value"] < ALPHA
    parts.append(f"fewer than {name} on {t['fewer']} start states, more on {t['more']} (p = {t['p_value']:.2g})")
  return Claim(ROLLOUTS, _verdict(ok), "SOE needed " + "; ".join(parts))


def log_ratio_test(a: list[float], b: list[float]) -> dict:
  """Per-seed values of two methods: the geometric mean of a / b and the paired t-test's two-sided
  p-value on log(a / b) (None for fewer than 2 seeds)."""
  d = np.log(np.asarray(a, float)) - np.log(np.asarray(b, float))
  p = float(stats.ttest_1samp(d, 0.0).pvalue) if len(d) > 1 and np.std(d) > 0 else None
  return dict(ratio=float(math.exp(d.mean())), p_value=p)


def jerk_claim(m: dict) -> Claim:
  soe, sime, dp = m.get("soe"), m.get("sime"), m.get("dp")
  if not (soe and sime and dp):
    return Claim(JERK, "not measured", "needs soe, sime and dp runs")
  tests = {}
  for name, a, b in (("SIME / DP", sime, dp), ("SIME / SOE", sime, soe), ("SOE / DP", soe, dp)):
    pairs = _seed_pairs(a, b, lambda run: run.get("jerk"))
    tests[name] = log_ratio_test([x for _, x in pairs], [y for y, _ in pairs])
  p = lambda t: "-" if t["p_value"] is None else f"{t['p_value']:.2g}"
  shown = ", ".join(f"{k} {t['ratio']:.2f}x (p = {p(t)})" for k, t in tests.items())
  needed = [tests[k] for k in ("SIME / DP", "SIME / SOE")]
  if any(t["p_value"] is None for t in needed):  # the test is across training seeds
    return Claim(JERK, "untested", f"{shown}: its test needs two training seeds or more")
  ok = all(t["ratio"] > 1 and t["p_value"] < ALPHA for t in needed)
  return Claim(JERK, _verdict(ok), shown)


def claims(rows: list[dict], task: str) -> list[Claim]:
  m = _by_method(rows, task)
  return [success_claim(m), pass_claim(m), rollouts_claim(m), jerk_claim(m)]
