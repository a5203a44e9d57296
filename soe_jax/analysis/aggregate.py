"""Compare finished runs: one table over tasks x methods, mean ± std over training seeds, each method
paired with its round 0 and with the control.

`python -m soe_jax aggregate RUNS_DIR [--out=RUNS_DIR/comparison]` finds every run directory under
RUNS_DIR (a `metrics.jsonl` beside a `config.json`, with the `outcomes.json` its report wrote) and
writes `<out>.md` and `<out>.csv` (`write`). Success rates carry the pooled episode count and 95%
Wilson interval. Every run of a training seed is evaluated on the same start states with the same
sampling keys, so each method's last round is compared state by state with its round 0 and with the
control of the same seed and settings (`method` control: the same re-fits without new data): states
gained and lost over all seeds, the difference per seed as mean ± standard deviation over seeds, and
the Cochran-Mantel-Haenszel test over the (seed, state) pairs (one seed: McNemar's exact test).
"""

from __future__ import annotations

import csv
import io
import json
import os

from absl import logging

from soe_jax import metrics
from soe_jax.analysis import report
from soe_jax.analysis.tables import markdown, mean_std
from soe_jax.experiment import rundir, runlog, schema
from soe_jax.runtime import atomic, faults
from soe_jax.runtime.errors import UserError

CONTROL = "control"
_PER_SEED = ("pass_at_k", "jerk", "rollouts", "kept", "kept_length", "sr_before", "sr_after", "improvement_rel", "seed")


def find_runs(root: str) -> list[str]:
  """Run directories (with a metrics.jsonl) under `root`, sorted."""
  found = []
  for dirpath, _, files in os.walk(root):
    if "metrics.jsonl" in files and "config.json" in files:
      found.append(dirpath)
  return sorted(found)


def settings(workdir: str) -> dict:
  """The run's saved config, flattened, without what seeds, places and logs it."""
  with open(os.path.join(workdir, "config.json")) as f:
    saved = rundir.with_added(json.load(f))  # older runs lack added fields
  return {k: v for k, v in runlog.flatten(saved).items() if schema.is_setting(k)}


def _variants(settings: list[dict]) -> list[str]:
  """For runs of one task and method: each one's values of the fields on which they differ ('' if none)."""
  keys = sorted({k for s in settings for k in s if any(t.get(k) != s.get(k) for t in settings)})
  return [", ".join(f"{k}={s.get(k)}" for k in keys) for s in settings]


def _control_key(task: str, seed, settings: dict) -> str:
  """What a run shares with its control: task, seed and every setting but the arm's."""
  same = {k: v for k, v in settings.items() if not k.startswith(schema.ARM)}
  return json.dumps([task, seed, same], sort_keys=True)


def _outcomes(workdir: str) -> dict:
  path = os.path.join(workdir, report.OUTCOMES_FILE)
  if not os.path.exists(path):
    return {"evaluate": {}, "explore": {}}
  with open(path) as f:
    return json.load(f)


def _check_base_path(control: dict, run: dict, control0, run0) -> None:
  """A run that differs from its control in a field that refits round 0 but keeps its base path
  (`schema.SAME_BASE_PATH`) must have evaluated round 0 as the control did, state by state."""
  differs = [k for k in schema.SAME_BASE_PATH if control["settings"].get(k) != run["settings"].get(k)]
  if differs and control0 != run0:
    raise UserError(
      f"{run['workdir']} differs from its control {control['workdir']} in {', '.join(differs)}, which keeps the base "
      "path, but their round-0 evaluations differ: they are not paired"
    )


def comparison(pairs: list[tuple]) -> dict | None:
  """`metrics.pooled_comparison` of [(reference, method)] per seed (None if there are none)."""
  pairs = [(a, b) for a, b in pairs if a is not None and b is not None]
  if not pairs:
    return None
  if any(len(a) != len(b) for a, b in pairs):
    raise ValueError("paired runs were evaluated on different numbers of start states")
  return dict(metrics.pooled_comparison(pairs), seeds=len(pairs))


def paired_cell(c: dict | None) -> str:
  """'+3.5 ± 2.1 pts, 30 / 16, p=0.04' (mean ± std over seeds; gained / lost; the pooled p-value)."""
  if c is None:
    return "-"
  spread = f" ± {100 * c['difference_std']:.1f}" if c["seeds"] > 1 else ""
  return f"{100 * c['difference_mean']:+.1f}{spread} pts, {c['gained']} / {c['lost']}, p={c['p_value']:.3g}"


HEADER = [
  "task",
  "method",
  "variant",
  "seeds",
  "pass_at_k",
  "jerk",
  "rollouts",
  "kept",
  "kept_length",
  "sr_before",
  "sr_after",
  "sr_after_episodes",
  "sr_after_wilson",
  "improvement_abs",
  "improvement_rel",
  "vs_round0",
  "vs_round0_p",
  "vs_control",
  "vs_control_p",
  "round_wall_s",
]


def _controls(runs: list[dict]) -> dict:
  """{control key: the control run every run with that key pairs with}: a control arm (`control`, with
  whatever variants: its own round 0 under `protocol=` or `style=`), the plain `control` where several
  share a key (the action range's and frame's controls differ from it in arm fields only, so they pair
  with it as arms do)."""
  controls: dict[str, dict] = {}
  for s in runs:
    if s["method"].split("-")[0] != CONTROL:
      continue
    key = _control_key(s["task"], s["seed"], s["settings"])
    if key not in controls or (s["method"] == CONTROL and controls[key]["method"] != CONTROL):
      controls[key] = s
  return controls


def rows(workdirs: list[str]) -> list[dict]:
  """One row per task, method and variant (runs whose configs differ in more than the seed and
  placement get a row each, named by the fields that differ), numbers as mean ± std over seeds; of two
  runs with the same config and seed, the first counts."""
  runs = []
  for w in workdirs:
    s = report.summarize(w)
    s["settings"], s["outcomes"] = settings(w), _outcomes(w)
    s["last"] = str(s["rounds"][-1]) if s["rounds"] else None
    runs.append(s)
  controls = _controls(runs)
  control_arms = {(c["task"], c["method"]) for c in controls.values()}
  by_method: dict[tuple, list[dict]] = {}
  for s in runs:
    by_method.setdefault((s["task"], s["method"]), []).append(s)
  groups: dict[tuple, list[dict]] = {}
  for (task, method), found in by_method.items():
    for s, v in zip(found, _variants([r["settings"] for r in found])):
      group = groups.setdefault((task, method, v), [])
      if first := next((r for r in group if r["seed"] == s["seed"]), None):
        logging.warning("%s repeats seed %s of %s with the same config; left out of the table",
                        s["workdir"], s["seed"], first["workdir"])  # fmt: skip
        continue
      group.append(s)
  out = []
  order = lambda g: (g[0][0], g[0][:2] in control_arms, g[0][1:])
  for (task, method, v), group in sorted(groups.items(), key=order):
    after = [r for r in group if "sr_after" in r]
    n = sum(r["sr_episodes"] for r in after)
    successes = sum(int(round(r["sr_after"] * r["sr_episodes"])) for r in after)
    lo, hi = metrics.wilson_interval(successes, n)
    evaluated = lambda r, rnd: r["outcomes"]["evaluate"].get(rnd) if rnd is not None else None
    vs_round0 = comparison([(evaluated(r, "0"), evaluated(r, r["last"])) for r in after if r["last"] != "0"])
    vs_control = None
    if (task, method) not in control_arms:
      pairs = []
      for r in after:
        control = controls.get(_control_key(task, r["seed"], r["settings"]))
        if control is not None:
          _check_base_path(control, r, evaluated(control, "0"), evaluated(r, "0"))
          pairs.append((evaluated(control, r["last"]), evaluated(r, r["last"])))
      vs_control = comparison(pairs)
    out.append(
      dict(
        task=task,
        method=method,
        variant=v,
        seeds=len(group),
        pass_at_k=mean_std([r.get("pass_at_k") for r in group]),
        jerk=mean_std([r.get("jerk") for r in group]),
        rollouts=mean_std([r.get("rollouts") for r in group]),
        kept=mean_std([r.get("kept") for r in group]),
        kept_length=mean_std([r.get("kept_length") for r in group]),
        sr_before=mean_std([r.get("sr_before") for r in group]),
        sr_after=mean_std([r.get("sr_after") for r in group]),
        sr_after_episodes=n,
        sr_after_wilson=f"[{lo:.3f}, {hi:.3f}]" if n else None,
        improvement_abs=mean_std([r.get("improvement_abs") for r in group]),
        improvement_rel=mean_std([r.get("improvement_rel") for r in group]),
        vs_round0=paired_cell(vs_round0),
        vs_round0_p=None if vs_round0 is None else vs_round0["p_value"],
        vs_control=paired_cell(vs_control),
        vs_control_p=None if vs_control is None else vs_control["p_value"],
        round_wall_s=mean_std([r.get("round_wall_s") for r in group]),
        comparisons=dict(round0=vs_round0, control=vs_control),
        per_seed={k: [r.get(k) for r in group] for k in _PER_SEED},
        runs=group,
        sr_after_pooled=(successes, n, lo, hi),
      )
    )
  return out


def aggregate(workdirs: list[str]) -> tuple[str, str]:
  """(markdown, csv) of `rows(workdirs)`."""
  table = rows(workdirs)
  md = markdown(HEADER, (["-" if r[h] is None else r[h] for h in HEADER] for r in table))
  buf = io.StringIO()
  w = csv.DictWriter(buf, fieldnames=HEADER, extrasaction="ignore")
  w.writeheader()
  w.writerows(table)
  return md, buf.getvalue()


def write(root: str, out: str | None = None) -> tuple[list[str], str, str]:
  """Aggregate the runs under `root` into `<out>.md` and `<out>.csv` (default `out`: `root/comparison`)
  -> (the runs, the markdown, `out`); `UserError` (nothing written) if there are no runs."""
  runs = find_runs(root)
  if not runs:
    raise UserError(f"no run directories (metrics.jsonl + config.json) under {root!r}")
  md, csv_text = aggregate(runs)
  out = out or os.path.join(root, "comparison")
  with faults.site("comparison"):
    for ext, text in (("md", md), ("csv", csv_text)):
      atomic.write_text(f"{out}.{ext}", text)
  return runs, md, out
