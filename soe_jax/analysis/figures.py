"""Figures of the claims, drawn from the committed runs: each is computed as plotted data first (a JSON
file beside the picture, which a test recomputes from the records), then drawn from that data.

- `forest`: each method's success against the control per task and protocol folder: the per-seed
  differences, the moderated seed-level estimate and its 95% interval (`claims.success_fits`), and for
  SOE the number its claim is tested against;
- `kept`: the oracle arms (the demonstrator's episodes from the kept start states) against the same
  method's own episodes, per task, the same way;
- `rounds`: success per round with a line per training seed (`over_rounds`).

In the documents a figure is the line `<!-- figure KIND: ARG ... PATH.png -->` (`results.figures`).
"""

from __future__ import annotations

import json
import math

import numpy as np
from matplotlib.figure import Figure

from soe_jax.analysis import aggregate, claims, over_rounds
from soe_jax.analysis import seed_level as sl
from soe_jax.runtime import atomic

# The methods in the order the forest draws them; the control against round 0 last.
ORDER = ("dp", "sime", "soe", "soe_steer")


def _entry(task: str, folder: str, arm: str, against: str, test: sl.Test, **extra) -> dict:
  finite = lambda x: None if x is None or math.isnan(x) else round(float(x), 6)
  return dict(task=task, folder=folder, arm=arm, against=against, per_seed=[round(d, 6) for d in test.d],
              estimate=finite(test.estimate), low=finite(test.low), high=finite(test.high),
              p_value=finite(test.p_value), df=test.df, **extra)  # fmt: skip


def forest_data(folders: list[str]) -> dict:
  """Per folder and task, each method's last round against the control (and the control against
  round 0) by the moderated test; SOE's entry carries the tested number and the verdict."""
  entries = []
  for folder in folders:
    rows = aggregate.rows(aggregate.find_runs(folder))
    for task in sorted({r["task"] for r in rows}):
      fits = claims.success_fits(rows, task)
      if len(fits) < 3:
        continue
      lay = claims.layout(claims.rates(fits))
      arms = [m for m in ORDER if m in lay.names] + sorted(set(lay.names) - set(ORDER) - {"control", "round 0"})
      for arm, test in zip(arms, lay.tests([(a, "control") for a in arms])):
        extra = {}
        if arm == "soe":
          tested = claims.tested_gain(lay)[1]
          extra = dict(tested=round(tested, 6), verdict=sl.verdict(test, tested))
        entries.append(_entry(task, folder, arm, "control", test, **extra))
      (null,) = lay.tests([("control", "round 0")])
      entries.append(_entry(task, folder, "control", "round 0", null))
  return dict(kind="forest", folders=list(folders), entries=entries)


def kept_data(folder: str, pairs: list[str]) -> dict:
  """Per task of `folder`'s runs (all its parts), each ARM:REFERENCE (an oracle arm against the same
  method's own episodes) by the moderated test over the fits the pairs name, the control and round 0."""
  rows = aggregate.rows(aggregate.find_runs(folder))
  entries = []
  for task in sorted({r["task"] for r in rows}):
    named = {m for p in pairs for m in p.split(":")} | {"control", "round 0"}
    fits = {k: v for k, v in claims.success_fits(rows, task, oracle=True).items() if k in named}
    lay = claims.layout(claims.rates(fits))
    present = [(a, b) for a, b in (p.split(":") for p in pairs) if a in lay.names and b in lay.names]
    for (arm, ref), test in zip(present, lay.tests(present)):
      entries.append(_entry(task, folder, arm, ref, test))
  return dict(kind="kept", folders=[folder], pairs=list(pairs), entries=entries)


def rounds_data(folder: str) -> dict:
  """Per task and method of `folder`'s runs of several rounds: success per round, per seed."""
  rows = over_rounds.multi_round(aggregate.rows(aggregate.find_runs(folder)))
  entries = []
  for row in rows:
    if row["variant"]:
      continue
    rounds = over_rounds.rounds_of(row)
    per_seed = {
      str(run["seed"]): [round(float(np.mean(run["outcomes"]["evaluate"][str(r)])), 6) for r in rounds]
      for run in row["runs"]
    }
    entries.append(dict(task=row["task"], method=row["method"], rounds=rounds, success=per_seed))
  return dict(kind="rounds", folders=[folder], entries=entries)


def _forest_axes(ax, entries: list[dict], title: str) -> None:
  """Rows of (task, arm): per-seed points, the estimate with its interval, a tested number if any."""
  labels = []
  for i, e in enumerate(entries):
    y = len(entries) - 1 - i
    labels.append((y, f"{e['task']}: {e['arm']} - {e['against']}"))
    color = "C3" if e["arm"] == "soe" or e["arm"].startswith("soe-") else "C0"
    if e["low"] is not None:
      ax.plot([100 * e["low"], 100 * e["high"]], [y, y], color=color, linewidth=2)
    ax.plot([100 * e["estimate"]], [y], "o", color=color, markersize=7)
    ax.plot([100 * d for d in e["per_seed"]], [y + 0.25] * len(e["per_seed"]), "x", color="0.35", markersize=5)
    if e.get("tested") is not None:
      ax.plot([100 * e["tested"]], [y], marker="|", color="k", markersize=16, markeredgewidth=2)
      ax.annotate(e["verdict"], (100 * e["tested"], y), xytext=(6, -12), textcoords="offset points", fontsize=8)
  ax.axvline(0, color="0.6", linewidth=1)
  ax.set_yticks([y for y, _ in labels], [t for _, t in labels], fontsize=8)
  ax.set_xlabel("difference in success (points): estimate and 95% interval (seed level, moderated); x: each seed")
  ax.set_title(title, fontsize=10)


def draw_forest(data: dict, path: str) -> None:
  entries = data["entries"]
  fig = Figure(figsize=(10, 0.42 * len(entries) + 1.6))
  ax = fig.subplots()
  title = (
    "Each method against the control (the control against round 0 last); |: the paper's number SOE is tested against"
  )
  _forest_axes(ax, entries, title)
  fig.tight_layout()
  fig.savefig(path, dpi=100, metadata={"Software": None})


def draw_kept(data: dict, path: str) -> None:
  entries = data["entries"]
  fig = Figure(figsize=(10, 0.5 * len(entries) + 1.6))
  _forest_axes(
    fig.subplots(), entries, "The demonstrator's episodes from the kept start states against the method's own"
  )
  fig.tight_layout()
  fig.savefig(path, dpi=100, metadata={"Software": None})


def draw_rounds(data: dict, path: str) -> None:
  tasks = sorted({e["task"] for e in data["entries"]})
  fig = Figure(figsize=(7, 4.2 * len(tasks)))
  axes = fig.subplots(len(tasks), 1, squeeze=False)[:, 0]
  methods = over_rounds.METHODS
  for ax, task in zip(axes, tasks):
    for e in (e for e in data["entries"] if e["task"] == task):
      color = f"C{(methods + (e['method'],)).index(e['method'])}"
      style = "--" if e["method"] == "control" else "-"
      success = 100 * np.array(list(e["success"].values()))
      for line in success:
        ax.plot(e["rounds"], line, style, color=color, linewidth=0.8, alpha=0.45)
      ax.plot(e["rounds"], success.mean(0), style, color=color, marker="o", linewidth=2,
              label=f"{e['method']} ({len(success)} seeds; thin: each seed)")  # fmt: skip
    ax.set(title=f"{task}: success per round (evaluation states)", xlabel="round", ylabel="success (%)")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.legend(loc="best", fontsize=8)
  fig.tight_layout()
  fig.savefig(path, dpi=100, metadata={"Software": None})


# kind -> (plotted data from the marker's arguments, drawing)
KINDS = {
  "forest": (lambda args: forest_data(args), draw_forest),
  "kept": (lambda args: kept_data(args[0], args[1:]), draw_kept),
  "rounds": (lambda args: rounds_data(args[0]), draw_rounds),
}


def data_path(path: str) -> str:
  """The plotted data's file beside a figure's PNG."""
  return path[: -len(".png")] + ".json" if path.endswith(".png") else path + ".json"


def make(kind: str, args: list[str], path: str) -> dict:
  """Compute `kind`'s plotted data from `args`, write it beside `path` and draw `path` -> the data."""
  compute, draw = KINDS[kind]
  data = compute(args)
  atomic.write_text(data_path(path), json.dumps(data, indent=1) + "\n")
  draw(data, path)
  return data
