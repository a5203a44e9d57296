"""Compare finished runs: one table over tasks x methods, mean ± std over seeds.

  python -m soe_jax.aggregate RUNS_DIR [--out=RUNS_DIR/comparison]

Finds every run directory under RUNS_DIR (a `metrics.jsonl` beside a `config.json`) and writes
`<out>.md` and `<out>.csv`; success rates carry the pooled episode count and 95% Wilson interval.
"""

from __future__ import annotations

import csv
import io
import json
import os

import numpy as np
from absl import app, flags, logging

from soe_jax import cli, metrics, report, runlog

flags.DEFINE_string("out", None, "Output path without extension (default RUNS_DIR/comparison).")
FLAGS = flags.FLAGS


def find_runs(root: str) -> list[str]:
  """Run directories (with a metrics.jsonl) under `root`, sorted."""
  found = []
  for dirpath, _, files in os.walk(root):
    if "metrics.jsonl" in files and "config.json" in files:
      found.append(dirpath)
  return sorted(found)


def _mean_std(xs) -> str:
  xs = [x for x in xs if x is not None]
  if not xs:
    return "-"
  return f"{np.mean(xs):.3g} ± {np.std(xs):.2g}" if len(xs) > 1 else f"{xs[0]:.3g}"


_NOT_SETTINGS = ("seed", "rounds.round0_dir")


def _settings(workdir: str) -> dict:
  """The run's saved config, flattened, without what seeds and places it."""
  with open(os.path.join(workdir, "config.json")) as f:
    return {k: v for k, v in runlog.flatten(json.load(f)).items() if k not in _NOT_SETTINGS}


def _variants(settings: list[dict]) -> list[str]:
  """For runs of one task and method: each one's values of the fields on which they differ ('' if none)."""
  keys = sorted({k for s in settings for k in s if any(t.get(k) != s.get(k) for t in settings)})
  return [", ".join(f"{k}={s.get(k)}" for k in keys) for s in settings]


def aggregate(workdirs: list[str]) -> tuple[str, str]:
  """(markdown, csv): one row per task, method and variant (runs whose configs differ in more than the
  seed get a row each, named by the fields that differ), mean ± std over seeds; success rates also with
  the 95% Wilson interval of all their episodes pooled, and the episode count; the wall time of a
  round (explore, re-fit, evaluate) in seconds. Of two runs with the same config and seed, the first
  counts."""
  by_method: dict[tuple, list[tuple[dict, dict]]] = {}
  for w in workdirs:
    s = report.summarize(w)
    by_method.setdefault((s["task"], s["method"]), []).append((s, _settings(w)))
  groups: dict[tuple, list[dict]] = {}
  for (task, method), found in by_method.items():
    for (s, _), v in zip(found, _variants([settings for _, settings in found])):
      runs = groups.setdefault((task, method, v), [])
      if s["seed"] in [r["seed"] for r in runs]:
        logging.warning(
          "%s repeats seed %s of %s with the same config; left out of the table",
          s["workdir"],
          s["seed"],
          runs[0]["workdir"],
        )
        continue
      runs.append(s)
  header = [
    "task",
    "method",
    "variant",
    "seeds",
    "pass_at_k",
    "jerk",
    "rollouts",
    "sr_before",
    "sr_after",
    "sr_after_episodes",
    "sr_after_wilson",
    "improvement_abs",
    "improvement_rel",
    "round_wall_s",
  ]
  rows = []
  for (task, method, v), runs in sorted(groups.items()):
    after = [r for r in runs if "sr_after" in r]
    n = sum(r["sr_episodes"] for r in after)
    successes = sum(int(round(r["sr_after"] * r["sr_episodes"])) for r in after)
    lo, hi = metrics.wilson_interval(successes, n)
    rows.append(
      dict(
        task=task,
        method=method,
        variant=v,
        seeds=len(runs),
        pass_at_k=_mean_std([r.get("pass_at_k") for r in runs]),
        jerk=_mean_std([r.get("jerk") for r in runs]),
        rollouts=_mean_std([r.get("rollouts") for r in runs]),
        sr_before=_mean_std([r.get("sr_before") for r in runs]),
        sr_after=_mean_std([r.get("sr_after") for r in runs]),
        sr_after_episodes=n,
        sr_after_wilson=f"[{lo:.3f}, {hi:.3f}]",
        improvement_abs=_mean_std([r.get("improvement_abs") for r in runs]),
        improvement_rel=_mean_std([r.get("improvement_rel") for r in runs]),
        round_wall_s=_mean_std([r.get("round_wall_s") for r in runs]),
      )
    )
  md = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
  md += ["| " + " | ".join(str(r[h]) for h in header) + " |" for r in rows]
  buf = io.StringIO()
  w = csv.DictWriter(buf, fieldnames=header)
  w.writeheader()
  w.writerows(rows)
  return "\n".join(md) + "\n", buf.getvalue()


def main(argv):
  if len(argv) != 2:
    raise app.UsageError("usage: python -m soe_jax.aggregate RUNS_DIR [--out=PATH]")
  root = argv[1]
  runs = find_runs(root)
  if not runs:
    raise app.UsageError(f"no run directories (metrics.jsonl + config.json) under {root!r}")
  md, csv_text = aggregate(runs)
  out = FLAGS.out or os.path.join(root, "comparison")
  with open(out + ".md", "w") as f:
    f.write(md)
  with open(out + ".csv", "w") as f:
    f.write(csv_text)
  print(md)
  print(f"{len(runs)} runs -> {out}.md, {out}.csv")


if __name__ == "__main__":
  cli.run(main, mjx=False)
