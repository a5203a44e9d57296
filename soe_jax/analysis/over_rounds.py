"""Self-improvement over several rounds, from a campaign's runs (`aggregate.rows`): the paper's
simulation figure (success per round, mean and a band of one standard deviation over training seeds,
beside the exploration's Pass@5 and rollouts per round), its table, and its claim that only SOE
improves monotonically.

Every round of a training seed is evaluated on the same start states with the same sampling keys, so
each round is compared state by state with the round before it (the CMH test over (seed, state)
pairs, `metrics.pooled_comparison`, in the table) and, for the claim, at the seed level (`seed_level`):
a method improves monotonically when every round is above the one before at seed-level p < 0.05, the
between-seed variance pooled over every step of the task's methods.
"""

from __future__ import annotations

import json
from itertools import pairwise

import numpy as np
from matplotlib.figure import Figure

from soe_jax import metrics
from soe_jax.analysis import claims, seed_level
from soe_jax.analysis.claims import Claim
from soe_jax.analysis.tables import markdown, spread

ALPHA = 0.05
# The methods of the paper's figure, in its order; the control is drawn beside them.
METHODS = ("dp", "sime", "soe", "control")
ROUNDS = "Only SOE improves monotonically over rounds"


def rounds_of(row: dict) -> list[int]:
  """The rounds every run of a row has evaluated (0, 1, ...)."""
  common = set.intersection(*(set(r["rounds"]) for r in row["runs"]))
  return sorted(common)


def multi_round(rows: list[dict]) -> list[dict]:
  """The rows whose every run has evaluated two rounds or more after round 0."""
  return [r for r in rows if len(rounds_of(r)) > 2]


def _per_seed(row: dict, field: str, rounds: list[int]) -> np.ndarray:
  """(seeds, rounds) of a per-round summary field (NaN where a round has none, e.g. round 0's Pass@5)."""
  out = []
  for run in row["runs"]:
    by_round = dict(zip(run["rounds"], run[field]))
    out.append([np.nan if by_round.get(r) is None else by_round[r] for r in rounds])
  return np.asarray(out, float)


def steps(row: dict) -> list[dict]:
  """Each round against the one before it, paired state by state within each seed and pooled."""
  rounds = rounds_of(row)
  out = []
  for prev, cur in zip(rounds, rounds[1:]):
    pairs = [(run["outcomes"]["evaluate"][str(prev)], run["outcomes"]["evaluate"][str(cur)]) for run in row["runs"]]
    out.append(dict(metrics.pooled_comparison(pairs), round=cur))
  return out


def step_tests(rows: list[dict]) -> dict[str, list[seed_level.Test]]:
  """{method: the moderated seed-level test of each of its steps (each round against the one before)},
  the family being every round of every row given (one task's methods; round 0 one fit where every row
  evaluated the same round 0, as methods sharing it do)."""
  per_round = {
    (row["method"], r): {run["seed"]: run["outcomes"]["evaluate"][str(r)] for run in row["runs"]}
    for row in rows
    for r in rounds_of(row)
  }
  shared = len({json.dumps(v, sort_keys=True) for (_, r), v in per_round.items() if r == 0}) == 1
  name = lambda method, r: "round 0" if shared and r == 0 else f"{method} {r}"
  fits = {name(m, r): {seed: float(np.mean(o)) for seed, o in v.items()} for (m, r), v in per_round.items()}
  lay = claims.layout(fits)
  return {
    row["method"]: lay.tests([(name(row["method"], b), name(row["method"], a)) for a, b in pairwise(rounds_of(row))])
    for row in rows
  }


def improves_every_round(tests: list[seed_level.Test]) -> bool:
  """Every step up at seed-level p < 0.05."""
  return all(seed_level.verdict(t, 0.0) == seed_level.REPRODUCED for t in tests)


def _cells(x: np.ndarray, scale: float, fmt: str) -> list[str]:
  """Per round (columns of x, NaN where a seed has no value): mean ± sample std over seeds."""
  return [spread(col, scale, "", fmt=fmt) for col in x.T]


def table(rows: list[dict]) -> str:
  """Per task and method: success per round (mean ± std over seeds, %), each round against the one
  before (mean difference in points, pooled p), and the exploration's Pass@5 and rollouts per round."""
  rows = multi_round(rows)
  if not rows:
    return ""
  width = max(len(rounds_of(r)) for r in rows)
  out = []
  for row in rows:
    rounds = rounds_of(row)
    success = _cells(_per_seed(row, "success_per_round", rounds), 100, ".1f")
    success += ["-"] * (width - len(success))
    step = "; ".join(f"{100 * s['difference_mean']:+.1f} pts, p={s['p_value']:.2g}" for s in steps(row))
    explored = [r for r in rounds if r > 0]
    passes = " / ".join(_cells(_per_seed(row, "pass_at_k_per_round", explored), 100, ".0f"))
    rollouts = " / ".join(_cells(_per_seed(row, "rollouts_per_round", explored), 1, ".0f"))
    if row["method"] == "control":
      passes = rollouts = "-"
    method = f"{row['method']}{row['variant'] and ' (' + row['variant'] + ')'}"
    out.append([row["task"], method, row["seeds"], *success, step, passes, rollouts])
  header = ["task", "method", "seeds", *(f"success, round {r}" for r in range(width)),
            "each round vs the one before: difference, pooled p", "Pass@5 per round", "rollouts per round"]  # fmt: skip
  return markdown(header, out)


def claim(rows: list[dict], task: str) -> Claim | None:
  """The paper's claim that only SOE improves monotonically over rounds, tested on `task`'s rows of
  several rounds at the seed level (None when it has no SOE row of several rounds): reproduced when
  each of SOE's steps is up at p < 0.05 and no dp or sime row's every step is; contradicted when one of
  SOE's steps has its interval below 0, or dp or sime improves every round too; fewer than 3 seeds: an
  anecdote; inconclusive otherwise."""
  m = {r["method"]: r for r in multi_round(rows) if r["task"] == task and not r["variant"]}
  if "soe" not in m:
    return None
  others = [k for k in ("dp", "sime") if k in m]
  tests = step_tests(list(m.values()))
  verdicts = [seed_level.verdict(t, 0.0) for t in tests["soe"]]
  if seed_level.ANECDOTE in verdicts:
    verdict = seed_level.ANECDOTE
  elif seed_level.CONTRADICTED in verdicts or any(improves_every_round(tests[k]) for k in others):
    verdict = seed_level.CONTRADICTED
  elif improves_every_round(tests["soe"]):
    verdict = seed_level.REPRODUCED
  else:
    verdict = seed_level.INCONCLUSIVE
  parts = []
  for name in [k for k in ("soe", "dp", "sime", "control") if k in m]:
    rounds = rounds_of(m[name])
    mean = np.nanmean(_per_seed(m[name], "success_per_round", rounds), axis=0)
    path = " -> ".join(f"{100 * x:.1f}" for x in mean)
    each = "; ".join(
      claims.describe(f"round {r}", t, s["p_value"]) for r, t, s in zip(rounds[1:], tests[name], steps(m[name]))
    )
    every = "improves every round" if improves_every_round(tests[name]) else "does not improve every round"
    parts.append(f"{name} {path}% ({every}: {each})")
  vs = "against " + ", ".join(others) if others else "no dp or sime runs to compare"
  return Claim(ROUNDS, verdict, f"{vs}: " + "; ".join(parts))


def figure(rows: list[dict], path: str) -> None:
  """Per task a row of three panels: success per round (mean over seeds, band of ± one standard
  deviation), Pass@5 and rollouts per exploration round, one line per method; saved to `path`."""
  rows = multi_round(rows)
  if not rows:
    raise ValueError("no runs of two rounds or more after round 0 to draw")
  tasks = sorted({r["task"] for r in rows})
  fig = Figure(figsize=(15, 4.2 * len(tasks)))
  axes = fig.subplots(len(tasks), 3, squeeze=False)
  for (ax_sr, ax_pass, ax_roll), task in zip(axes, tasks):
    found = {r["method"]: r for r in rows if r["task"] == task and not r["variant"]}
    order = [m for m in METHODS if m in found] + sorted(set(found) - set(METHODS))
    for name in order:
      row, color = found[name], f"C{(METHODS + tuple(order)).index(name)}"  # a method's color in every task
      rounds = rounds_of(row)
      style = dict(color=color, linestyle="--" if name == "control" else "-", marker="o")
      sr = 100 * _per_seed(row, "success_per_round", rounds)
      mean, std = sr.mean(axis=0), sr.std(axis=0, ddof=1) if len(sr) > 1 else np.zeros(len(rounds))
      ax_sr.plot(rounds, mean, label=f"{name} ({row['seeds']} seed{'s' if row['seeds'] > 1 else ''})", **style)
      ax_sr.fill_between(rounds, mean - std, mean + std, color=color, alpha=0.15)
      explored = [r for r in rounds if r > 0]
      if name != "control":
        ax_pass.plot(explored, 100 * np.nanmean(_per_seed(row, "pass_at_k_per_round", explored), axis=0), **style)
        ax_roll.plot(explored, np.nanmean(_per_seed(row, "rollouts_per_round", explored), axis=0), **style)
    ax_sr.set(title=f"{task}: success (base path, evaluation states)", xlabel="round", ylabel="success (%)")
    ax_sr.set_ylim(-3, 103)
    ax_sr.legend(loc="best", fontsize=8)
    ax_pass.set(title=f"{task}: Pass@5 of each exploration round", xlabel="round", ylabel="Pass@5 (%)")
    ax_pass.set_ylim(-3, 103)
    ax_roll.set(title=f"{task}: rollouts of each exploration round", xlabel="round", ylabel="rollouts")
    for ax in (ax_sr, ax_pass, ax_roll):
      ax.xaxis.get_major_locator().set_params(integer=True)
  fig.tight_layout()
  fig.savefig(path, dpi=100, metadata={"Software": None})
