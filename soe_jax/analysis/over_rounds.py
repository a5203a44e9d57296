"""Self-improvement over several rounds, from a campaign's runs (`aggregate.rows`): the paper's
simulation figure (success per round, mean and a band of one standard deviation over training seeds,
beside the exploration's Pass@5 and rollouts per round), its table, and its claim that only SOE
improves monotonically.

Every round of a training seed is evaluated on the same start states with the same sampling keys, so
each round is compared state by state with the round before it (the CMH test over (seed, state)
pairs, `metrics.pooled_comparison`). A method improves monotonically when every round's mean
difference from the one before is positive and its last round is above round 0 with p < 0.05.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from soe_jax import metrics
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


def improves_monotonically(row: dict) -> bool:
  rounds = rounds_of(row)
  first = [run["outcomes"]["evaluate"]["0"] for run in row["runs"]]
  last = [run["outcomes"]["evaluate"][str(rounds[-1])] for run in row["runs"]]
  overall = metrics.pooled_comparison(list(zip(first, last)))
  rising = all(s["difference_mean"] > 0 for s in steps(row))
  return rising and overall["difference_mean"] > 0 and overall["p_value"] < ALPHA


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
            "each round vs the one before: difference, p", "Pass@5 per round", "rollouts per round"]  # fmt: skip
  return markdown(header, out)


def claim(rows: list[dict], task: str) -> Claim | None:
  """The paper's claim that only SOE improves monotonically over rounds, tested on `task`'s rows of
  several rounds (None when it has no SOE row of several rounds)."""
  m = {r["method"]: r for r in multi_round(rows) if r["task"] == task and not r["variant"]}
  if "soe" not in m:
    return None
  others = [k for k in ("dp", "sime") if k in m]
  verdict = improves_monotonically(m["soe"]) and not any(improves_monotonically(m[k]) for k in others)
  parts = []
  for name in [k for k in ("soe", "dp", "sime", "control") if k in m]:
    rounds = rounds_of(m[name])
    mean = np.nanmean(_per_seed(m[name], "success_per_round", rounds), axis=0)
    path = " -> ".join(f"{100 * x:.1f}" for x in mean)
    parts.append(
      f"{name} {path}% ({'improves every round' if improves_monotonically(m[name]) else 'does not improve every round'})"
    )
  vs = "against " + ", ".join(others) if others else "no dp or sime runs to compare"
  return Claim(ROUNDS, "reproduced" if verdict else "not reproduced", f"{vs}: " + "; ".join(parts))


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
