"""The kill-anywhere harness: a smoke run (or campaign) SIGKILLed at a write site's kill point
(`runtime.faults`), then run again with the same command until it finishes, and what it left compared
with an uninterrupted run's.

A job is the toy task's `smoke,soe` run with its report, or a smoke campaign (control, dp and soe) on
it, each in a fresh Python process, as `python -m soe_jax run` / `campaign` would run them (the toy task
is registered first: it is not one of the package's). `trace(job)` runs it once uninterrupted, listing
the kill points it reached; `interrupted(job, kills)` runs it killed at each of `kills` in turn (each
in a fresh process that resumes the last), then to its end.
"""

from __future__ import annotations

import collections
import csv
import dataclasses
import glob
import json
import os
import pathlib
import subprocess
import sys

import numpy as np

from soe_jax.runtime import faults

REPO = pathlib.Path(__file__).resolve().parents[2]

_DRIVER = """
import sys
sys.path[:0] = [{repo!r}, {toy!r}]
import toy
from soe_jax.runtime import compile_cache
compile_cache.enable()
with toy.registered():
  if sys.argv[1] == "run":
    from soe_jax.analysis import report
    from soe_jax.experiment import loop
    loop.run(toy.get_config("smoke,soe"), sys.argv[2] + "/run", progress=False)
    report.write(sys.argv[2] + "/run")
  else:
    from soe_jax.analysis import campaign
    campaign.campaign({config!r}, {{}}, ["control", "dp", "soe"], sys.argv[2] + "/runs", sys.argv[2] + "/results",
                      False)
"""

JOBS = ("run", "campaign")


@dataclasses.dataclass(frozen=True)
class Kill:
  """SIGKILL at the n-th time the process reaches `when` of `site`."""

  site: str
  when: str
  n: int = 1

  def __str__(self) -> str:
    return f"{self.site}:{self.when}:{self.n}"


def _driver(tmp: pathlib.Path) -> str:
  path = tmp / "driver.py"
  toy = REPO / "tests" / "experiment"
  path.write_text(_DRIVER.format(repo=str(REPO), toy=str(toy), config=str(toy / "toy_config.py") + ":smoke"))
  return str(path)


def _launch(job: str, base: pathlib.Path, env: dict) -> subprocess.CompletedProcess:
  env = dict(os.environ, **env)
  return subprocess.run([sys.executable, _driver(base), job, str(base)], env=env, capture_output=True, text=True,
                        timeout=600, cwd=REPO)  # fmt: skip


def trace(job: str, base: pathlib.Path) -> list[Kill]:
  """Run `job` uninterrupted in `base`; -> every kill point it reached, in order."""
  base.mkdir(parents=True, exist_ok=True)
  log = base / "sites.log"
  proc = _launch(job, base, {faults.LOG_ENV: str(log)})
  assert proc.returncode == 0, proc.stderr[-3000:]
  seen, points = collections.Counter(), []
  for line in log.read_text().splitlines():
    site, when = line.split()
    seen[site, when] += 1
    points.append(Kill(site, when, seen[site, when]))
  return points


def interrupted(job: str, base: pathlib.Path, kills: list[Kill]) -> list[str]:
  """Run `job` in `base`, killed at each of `kills` in turn, each time in a new process that resumes the
  last, then run it to its end -> the warnings the resumed runs printed (one per line)."""
  base.mkdir(parents=True, exist_ok=True)
  warnings = []
  for kill in kills:
    proc = _launch(job, base, {faults.KILL_ENV: str(kill)})
    assert proc.returncode == -9, f"{job} was not killed at {kill} (exit {proc.returncode}): {proc.stderr[-2000:]}"
    warnings += [line for line in proc.stderr.splitlines() if line.startswith("warning:")]
  proc = _launch(job, base, {})
  assert proc.returncode == 0, f"{job} did not finish after {kills}: {proc.stderr[-3000:]}"
  return warnings + [line for line in proc.stderr.splitlines() if line.startswith("warning:")]


def killed_at_random(job: str, base: pathlib.Path, seconds: list[float]) -> None:
  """Run `job` in `base`, SIGKILLed after each of `seconds` in turn (a run that finishes first is left
  finished), then to its end."""
  base.mkdir(parents=True, exist_ok=True)
  for s in seconds:
    proc = subprocess.Popen([sys.executable, _driver(base), job, str(base)], cwd=REPO, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)  # fmt: skip
    try:
      proc.wait(timeout=s)
    except subprocess.TimeoutExpired:
      proc.kill()
      proc.wait()
  proc = _launch(job, base, {})
  assert proc.returncode == 0, proc.stderr[-3000:]


# -- what a finished job left ------------------------------------------------------------------------


def _timeless(x):
  """A record without its timings (wall and compile seconds, which no two runs share)."""
  if isinstance(x, dict):
    return {k: _timeless(v) for k, v in x.items() if not (k.startswith("time_") or k.endswith("_s"))}
  if isinstance(x, list):
    return [_timeless(v) for v in x]
  return x


def _metrics(path: str) -> list[dict]:
  lines = [json.loads(line) for line in pathlib.Path(path).read_text().splitlines()]
  keys = [(m["round"], m["phase"]) for m in lines]
  assert len(keys) == len(set(keys)), f"{path}: duplicate lines {keys}"
  return [_timeless(m) for m in lines]


def _episodes(path: str) -> list[dict]:
  from soe_jax.data import hdf5

  return hdf5.read_episodes(path)[0]


def _params(ckpt: str):
  from soe_jax.train import checkpoint

  return checkpoint.load(ckpt).state.params


def _run_dirs(root: pathlib.Path) -> list[pathlib.Path]:
  return sorted(p.parent for p in root.rglob("metrics.jsonl") if "results" not in p.parts[len(root.parts) :])


def left(job: str, base: pathlib.Path) -> dict:
  """What a finished job left that a resumed one must reproduce: per run directory its metrics lines,
  phase records (timings aside), outcomes, kept episodes and last policy's parameters; per results copy
  its metrics and outcomes; and the comparison table's rows (timings aside: its `round_wall_s`)."""
  out = {}
  for run in _run_dirs(base):
    name = str(run.relative_to(base))
    out[name, "metrics"] = _metrics(run / "metrics.jsonl")
    out[name, "outcomes"] = json.loads((run / "outcomes.json").read_text())
    config = json.loads((run / "config.json").read_text())
    round0 = pathlib.Path(config["rounds"]["round0_dir"] or run.parent / "round0")
    for record in sorted(glob.glob(f"{run}/rounds/*/*.json")) + sorted(glob.glob(f"{round0}/*/*.json")):
      out[name, os.path.relpath(record, base)] = _timeless(json.loads(pathlib.Path(record).read_text()))
    for data in sorted(glob.glob(f"{run}/data/*.hdf5")):
      out[name, os.path.basename(data)] = _episodes(data)
    last = max(int(r) for r in os.listdir(run / "rounds"))
    out[name, "params"] = _params(str(run / "rounds" / str(last) / "ckpt"))
  for copy in sorted(glob.glob(f"{base}/results/*/seed*/*")):
    rel = os.path.relpath(copy, base)
    out[rel, "metrics"] = _metrics(f"{copy}/metrics.jsonl")
    out[rel, "outcomes"] = json.loads(pathlib.Path(f"{copy}/outcomes.json").read_text())
  if os.path.exists(table := base / "results" / "comparison.csv"):
    with open(table) as f:
      out["comparison"] = [_timeless(row) for row in csv.DictReader(f)]  # (without round_wall_s)
  return out


def differences(a: dict, b: dict) -> list[str]:
  """The items of `left(...)` that differ between two finished jobs (empty: the same)."""
  import jax

  found = [f"{k}: only in one" for k in set(a) ^ set(b)]
  for k in sorted(set(a) & set(b), key=str):
    x, y = a[k], b[k]
    leaves = jax.tree.leaves(x), jax.tree.leaves(y)
    same = jax.tree.structure(x) == jax.tree.structure(y) and all(
      np.array_equal(np.asarray(u), np.asarray(v)) for u, v in zip(*leaves)
    )
    if not same:
      found.append(f"{k}: differs")
  return found


def unclaimed_files(base: pathlib.Path) -> list[str]:
  """Files a finished job left that no write site claims (`faults.SITES`' globs): a write without a site."""
  roots = _run_dirs(base) + [p.parent for p in base.rglob("demos.hdf5")]
  roots += [base / "results"] + [pathlib.Path(p) for p in glob.glob(f"{base}/results/*/seed*/*")]
  claimed = {
    os.path.normpath(f)
    for root in roots
    for globs, _ in faults.SITES.values()
    for g in globs
    for f in glob.glob(f"{root}/{g}", recursive=True)
  }
  ignored = {"sites.log", "driver.py", *faults.NOT_WRITES}
  return sorted(
    os.path.relpath(os.path.join(parent, name), base)
    for parent, _, files in os.walk(base)
    for name in files
    if os.path.normpath(os.path.join(parent, name)) not in claimed and name not in ignored
  )
