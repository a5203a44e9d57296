"""Round 0 on the workspace box against the demonstrations' action range, by distance outside it.

  python -m soe_jax study action_range results/campaign-workspace/lift [--out=results/action-range/lift.json]

Paired state by state and bucketed by how far each evaluation state's object starts outside the box
the demonstrations' range allowed. A campaign run with the methods `control` and `control+range=demonstrations` fits both round 0s from
the same demonstrations and evaluates them on the same start states with the same sampling keys. For
each training seed this rebuilds the demonstrations' action box (the normaliser the old rule fits on
the run's demonstrations, which the scripted demonstrator regenerates from `data.demo_seed`) and the
evaluation start states (`eval.seed`), measures each state's object (x, y) distance outside that box,
and pairs the two round 0s' outcomes per distance bucket. The input is the task's directory of the
campaign's results (`python -m soe_jax campaign ... --methods=control,control+range=demonstrations,...`,
every seed under it); the table is printed, and `--out` writes the record (command, commit, machine, per
seed the distances and both round 0s' per-state outcomes) that `python -m soe_jax results` tables.
"""

from __future__ import annotations

import dataclasses
import json
import os

import jax
import ml_collections
import numpy as np

from soe_jax import metrics
from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study
from soe_jax.analysis.tables import markdown, pct
from soe_jax.data.episodes import policy_frames
from soe_jax.experiment import phases, rundir, task
from soe_jax.experiment.loop import demonstrations
from soe_jax.policies import normalizer
from soe_jax.runtime import provenance
from soe_jax.runtime.errors import UserError

ARMS = ("control-range_demonstrations", "control")  # (reference, workspace)
BUCKETS = (("inside", 0.0, 0.0), ("< 5 mm", 0.0, 5.0), ("5-10 mm", 5.0, 10.0), (">= 10 mm", 10.0, np.inf))


def demonstrations_box(config: ml_collections.ConfigDict) -> tuple[np.ndarray, np.ndarray]:
  """The (lo, hi) robot0 positions, each (3,), that `policy.action_range = demonstrations` maps to
  [-1, 1] for `config`'s demonstrations."""
  env = task.env(config)
  frames = policy_frames(demonstrations(config, env, False), env.policy_obs_keys)
  norm = normalizer.fit(*frames, float(config.policy.normalizer_margin), env.obs_min_span, env.num_robots)
  lo, hi = (np.asarray(norm.unnormalize_actions(np.full(env.action_size, v)), np.float64)[:3] for v in (-1.0, 1.0))
  return lo, hi


def object_positions(config: ml_collections.ConfigDict) -> np.ndarray:
  """(N, 3): the object's start position at each evaluation start state."""
  env = task.env(config)
  state = jax.jit(jax.vmap(env.reset))(phases.evaluation_starts(config))
  return np.asarray(jax.device_get(state.obs["object"][:, :3]), np.float64)


def distance_outside(xy: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
  """(N,) m: how far each (x, y) lies outside the box [lo, hi] (0 inside)."""
  excess = np.maximum(lo[:2] - xy, 0.0) + np.maximum(xy - hi[:2], 0.0)
  return np.linalg.norm(excess, axis=-1)


def seed_entry(seed_dir: str) -> dict:
  """One seed's states: distances outside the demonstrations' box and both round 0s' outcomes."""
  missing = [a for a in ARMS if not os.path.exists(os.path.join(seed_dir, a, "outcomes.json"))]
  if missing:
    raise UserError(
      f"{seed_dir}: no finished {', '.join(missing)} run (campaign methods control,control+range=demonstrations)"
    )
  config = rundir.load_config(os.path.join(seed_dir, "control"))
  lo, hi = demonstrations_box(config)
  dist = distance_outside(object_positions(config)[:, :2], lo, hi)
  outcomes = {}
  for arm in ARMS:
    with open(os.path.join(seed_dir, arm, "outcomes.json")) as f:
      outcomes[arm] = json.load(f)["evaluate"]["0"]
  return dict(
    seed=int(config.seed),
    demonstrations_box=[np.round(lo, 5).tolist(), np.round(hi, 5).tolist()],
    distance_mm=np.round(1000 * dist, 2).tolist(),
    round0={"demonstrations": outcomes[ARMS[0]], "workspace": outcomes[ARMS[1]]},
  )


@dataclasses.dataclass(frozen=True)
class ActionRange(Study):
  name = "action_range"
  kind = "action_range"
  usage = "RESULTS/<task>"
  takes = "1"

  def run(self, paths, config=None):
    """Provenance, task, then `seeds`: each `seed<k>` directory's `seed_entry`."""
    (task_dir,) = paths
    source = provenance.header()
    seeds = sorted(d for d in os.listdir(task_dir) if d.startswith("seed"))
    if not seeds:
      raise UserError(f"{task_dir}: no seed<k> directories")
    task = os.path.basename(os.path.normpath(task_dir))
    return dict(source, task=task, seeds=[seed_entry(os.path.join(task_dir, s)) for s in seeds])

  @staticmethod
  def table(committed: records.Records) -> str:
    """A row per distance bucket and one over all states: states over the seeds of every record, round
    0's success under each range, states gained / lost by the workspace box, the pooled paired test
    (CMH over seeds and states)."""
    seeds = [s for _, r in committed for s in r["seeds"]]
    rows = []
    for name, low, high in BUCKETS + (("all", -np.inf, np.inf),):
      pairs = []
      for s in seeds:
        d = np.asarray(s["distance_mm"])
        m = (d == 0) if high == 0 else (d > 0) & (d >= low) & (d < high) if name != "all" else d >= 0
        pairs.append((np.asarray(s["round0"]["demonstrations"])[m], np.asarray(s["round0"]["workspace"])[m]))
      n = sum(len(a) for a, _ in pairs)
      if not n:
        rows.append([name, 0, "-", "-", "-", "-"])
        continue
      c = metrics.pooled_comparison([p for p in pairs if len(p[0])])
      old, new = (sum(int(np.sum(p[i])) for p in pairs) / n for i in (0, 1))
      rows.append([name, n, pct(old), pct(new), f"{c['gained']} / {c['lost']}", f"{c['p_value']:.3g}"])
    header = ["object outside the demonstrations' box", "states (all seeds)", "round 0, demonstrations' range",
              "round 0, workspace box", "gained / lost", "p (CMH)"]  # fmt: skip
    return markdown(header, rows)
