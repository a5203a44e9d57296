"""A run beside the committed campaign of its task and preset, so that one seed reads against the
committed seeds rather than alone: a section of the run's report (`report.md`, `context.png`) and the
lines `run` prints last.

The committed campaigns a report looks in are `COMMITTED`, folders of the repository's `results/`
(`python -m soe_jax campaign ... --results=results/NAME`). A run finds its campaign by its settings:
a committed run with the same task and every setting the same but the training seed and the arm's own
fields (`schema.ARM`: the method, how it explores, what it keeps) is of the same task and preset; a run
with any other setting changed (a field overridden on the command line, another preset) finds none,
and its report says nothing of the campaign.

Every arm of a committed seed is evaluated on that seed's start states with the same sampling keys, and
so is the run: its seed is one more seed of the campaign. The table gives each arm's success per
committed seed, their mean and, for each arm against the control, the seed-level test the claims use
(`claims.success_fits`, `seed_level.moderated`: each seed's paired difference, the seed-to-seed spread
pooled over the fits of that round 0): the difference, its 95% interval and p-value. The run's own
round 0 and last round stand beside them. Where the run's seed is a committed one, its per-state
outcomes are compared with the committed run's, state for state: the same outcomes mean this machine
reproduced that run.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
from matplotlib.figure import Figure

from soe_jax.analysis import aggregate, claims
from soe_jax.analysis import seed_level as sl
from soe_jax.analysis.tables import markdown, pct
from soe_jax.experiment import schema
from soe_jax.runtime import atomic, configfile

# The committed campaigns a run's report is compared with (folders under the repository's root).
COMMITTED = ("results/quick",)
# The arms shown, in order (a run of another arm gets a row of its own).
ARMS = ("round 0", "control", "dp", "sime", "soe")
FIGURE = "context.png"


def _key(settings: dict) -> str:
  """What a run shares with every arm of its campaign's seeds: its settings but the arm's fields."""
  return json.dumps({k: v for k, v in settings.items() if not k.startswith(schema.ARM)}, sort_keys=True)


def committed_runs(workdir: str, roots: tuple[str, ...] | None = None) -> tuple[str, list[str]] | None:
  """(folder, its runs) of the first committed campaign (`COMMITTED`, under the repository's root) whose
  runs share `workdir`'s task and settings but the seed and the arm; None if none does (or the
  repository's results are not here, as in an installed wheel)."""
  key = _key(aggregate.settings(workdir))
  here = os.path.realpath(workdir)
  for root in COMMITTED if roots is None else roots:
    folder = root if os.path.isabs(root) else os.path.join(configfile.REPO_ROOT, root)
    if not os.path.isdir(folder):
      continue
    found = [w for w in aggregate.find_runs(folder) if os.path.realpath(w) != here]
    found = [w for w in found if _key(aggregate.settings(w)) == key]
    if found:
      return root, found
  return None


def compare(workdir: str, roots: tuple[str, ...] | None = None) -> dict | None:
  """The run in `workdir` beside its committed campaign (None where there is none, or it has no control):
  the campaign's folder and seeds; per arm its success per committed seed, their mean and (against the
  control, from two seeds on) the seed-level test; the run's own seed, method, round-0
  and last-round success, and, where its seed is a committed one, how many states its outcomes share
  with that seed's committed run."""
  found = committed_runs(workdir, roots)
  if found is None:
    return None
  folder, runs = found
  rows = aggregate.rows(runs)
  mine = aggregate.rows([workdir])[0]["runs"][0]
  task = mine["task"]
  fits = claims.success_fits(rows, task)
  if not fits:  # (a campaign without its control is not one to read a run against)
    return None
  rates = claims.rates(fits)
  seeds = sorted({s for by_seed in rates.values() for s in by_seed})
  tests = {}
  if len(fits) > 2:
    lay = claims.layout(rates)
    others = [n for n in lay.names if n != "control"]
    if len(lay.seeds) > 1:
      tests = dict(zip(others, lay.tests([(n, "control") for n in others])))
    elif lay.seeds:  # one seed: its difference, with no interval
      y = dict(zip(lay.names, lay.y[0]))
      tests = {n: sl.Test((y[n] - y["control"],), y[n] - y["control"], *(math.nan,) * 4, 0, math.nan) for n in others}
  evaluated = mine["outcomes"]["evaluate"]
  method = mine["method"]
  last = mine["last"]
  own = {"round 0": evaluated.get("0")}
  if last not in (None, "0"):
    own[method] = evaluated[last]
  arms = [a for a in ARMS if a in rates] + [a for a in rates if a not in ARMS]
  if method not in arms and method in own:
    arms.append(method)
  same = {}
  if mine["seed"] in seeds:
    for arm, outcomes in own.items():
      theirs = fits.get(arm, {}).get(mine["seed"])
      if outcomes is not None and theirs is not None and len(theirs) == len(outcomes):
        same[arm] = (int(np.sum(np.asarray(theirs, bool) == np.asarray(outcomes, bool))), len(outcomes))
  return dict(
    folder=folder,
    task=task,
    seeds=seeds,
    arms=[
      dict(
        name=arm,
        per_seed={s: rates.get(arm, {}).get(s) for s in seeds},
        mean=float(np.mean(list(rates[arm].values()))) if rates.get(arm) else None,
        test=tests.get(arm),
        yours=None if own.get(arm) is None else float(np.mean(np.asarray(own[arm], float))),
      )
      for arm in arms
    ],
    seed=mine["seed"],
    method=method,
    states=len(evaluated.get("0", [])),
    same=same,
  )


def _test_cell(test: sl.Test | None) -> str:
  if test is None:
    return "-"
  if math.isnan(test.low):
    return f"{100 * test.estimate:+.1f} points (one seed: no interval)"
  return f"{100 * test.estimate:+.1f} points [{100 * test.low:+.1f}, {100 * test.high:+.1f}], p = {test.p_value:.2g}"


def _gain(c: dict, seed) -> float | None:
  """The run's method against round 0 on `seed` (None: the run's own seed), in points."""
  by = {a["name"]: a for a in c["arms"]}
  arm, base = by.get(c["method"]), by.get("round 0")
  if arm is None or base is None:
    return None
  a, b = (arm["yours"], base["yours"]) if seed is None else (arm["per_seed"].get(seed), base["per_seed"].get(seed))
  return None if a is None or b is None else 100 * (a - b)


def lines(c: dict) -> list[str]:
  """The comparison `c` (`compare`) as markdown: a table and what it says of the run's seed."""
  seeds = ("seeds " if len(c["seeds"]) > 1 else "seed ") + ", ".join(str(s) for s in c["seeds"])
  header = ["", f"your seed {c['seed']}", *(f"committed seed {s}" for s in c["seeds"]), "mean", "against the control"]
  rows = [
    [a["name"], pct(a["yours"]), *(pct(a["per_seed"][s]) for s in c["seeds"]), pct(a["mean"]), _test_cell(a["test"])]
    for a in c["arms"]
  ]
  out = [
    f"The committed campaign of this task and preset (`{c['folder']}`: the same settings but the training seed and "
    f"the arm) over training {seeds}: success on each seed's {c['states']} evaluation start states, every arm "
    "of a seed on the same states with the same sampling keys, as your run's. Round 0 is the shared base policy; the "
    "control re-fits without new data; dp, sime and soe explore, keep successes and re-fit. Against the control: "
    "each arm's difference from the control over the committed seeds, seed-level (each seed one paired difference, "
    "the seed-to-seed spread pooled over the arms), with its 95% interval and p-value.",
    "",
    *markdown(header, rows).splitlines(),
    "",
  ]
  mine = _gain(c, None)
  if mine is not None:
    theirs = [g for s in c["seeds"] if (g := _gain(c, s)) is not None]
    listed = ", ".join(f"{g:+.1f}" for g in theirs)
    out.append(
      f"Your {c['method']} against your round 0: {mine:+.1f} points; on the committed seeds {listed} points"
      + (f" (mean {np.mean(theirs):+.1f})." if theirs else ".")
    )
  if c["same"]:
    parts = [f"{arm} on {k} of {n} states" for arm, (k, n) in c["same"].items()]
    whole = all(k == n for k, n in c["same"].values())
    out.append(
      f"Your seed {c['seed']} is committed seed {c['seed']}: its per-state outcomes match the committed run's "
      + ", ".join(parts)
      + (" (this machine reproduced it)." if whole else " (the committed run was not reproduced exactly).")
    )
  elif mine is not None:
    out.append(f"Your seed {c['seed']} is not a committed one: it is one more seed beside them.")
  return out


def figure(c: dict) -> Figure:
  """Success per arm: each committed seed a grey dot, their mean a bar, the run's own a red star."""
  fig = Figure(figsize=(10, 6))
  ax = fig.subplots()
  names = [a["name"] for a in c["arms"]]
  for i, a in enumerate(c["arms"]):
    got = [(j, 100 * a["per_seed"][s]) for j, s in enumerate(c["seeds"]) if a["per_seed"][s] is not None]
    xs = [i + 0.08 * (j - (len(c["seeds"]) - 1) / 2) for j, _ in got]  # (side by side: equal rates stay apart)
    ax.scatter(xs, [y for _, y in got], color="0.5", zorder=2, label="committed seeds" if i == 0 else None)
    if a["mean"] is not None:
      ax.hlines(100 * a["mean"], i - 0.25, i + 0.25, color="k", zorder=3, label="their mean" if i == 0 else None)
  yours = [(i, 100 * a["yours"]) for i, a in enumerate(c["arms"]) if a["yours"] is not None]
  if yours:
    ax.scatter(*zip(*yours), marker="*", s=200, color="C3", zorder=4, label=f"your seed {c['seed']}")
  ax.set_xticks(range(len(names)), names)
  ax.set_ylim(-3, 103)
  seeds = ", ".join(str(s) for s in c["seeds"])
  ax.set(ylabel="success rate (%)", title=f"{c['task']}: your run beside the committed seeds {seeds} ({c['folder']})")
  ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3)
  fig.tight_layout()
  return fig


def section(workdir: str, roots: tuple[str, ...] | None = None) -> list[str]:
  """The report's section on the committed campaign, its figure drawn into `workdir` (no lines where the
  run has no committed campaign)."""
  c = compare(workdir, roots)
  if c is None:
    return []
  with atomic.replacing(os.path.join(workdir, FIGURE), suffix=".png") as tmp:
    figure(c).savefig(tmp, dpi=110)
  return ["## Your run beside the committed seeds", "", *lines(c), "", f"![your run beside the committed seeds]({FIGURE})",
          ""]  # fmt: skip
