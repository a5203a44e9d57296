"""What a round kept, episode by episode, against the demonstrations the run started from.

  python -m soe_jax study kept RUN_DIR [RUN_DIR ...] [--round=1] [--out=results/<study>/<name>.json]

For each run (a workdir of `run` or of a campaign), the episodes round `--round`'s exploration kept
(`data/round_<r>.hdf5`) and the run's demonstrations, each episode measured as:
- its length in control steps;
- the commanded grip-site position's step |a_t - a_(t-1)| in mm, at decision boundaries (t a multiple
  of `policy.n_action_steps`: a new action chunk starts there) and inside chunks, each averaged over
  the episode (and over the arms, on a two-arm task);
- the object's tilt: the largest angle between its up axis and the up axis it started with, and
  whether that passed `TIPPED_DEG` (tipped); the object is the first in the task's `object` vector
  (Transport: the hammer, which the arms turn on purpose);
- its grasps: how often the gripper command crosses from open to closed (on a two-arm task, the most
  of either arm), and whether more than once (re-grasped).
Printed as a table with a row per task and method (episodes pooled over seeds) and a row of the runs'
demonstrations; `--out` writes the record (command, commit, machine, and per run its method, seed and
per-episode numbers; the runs' configs are in their workdirs) for `results/`, where `python -m soe_jax
results` tables it.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from soe_jax.analysis import records
from soe_jax.analysis.studies.study import Study, setting
from soe_jax.analysis.tables import markdown
from soe_jax.data import hdf5
from soe_jax.envs import registry
from soe_jax.experiment import rundir
from soe_jax.runtime import atomic, provenance
from soe_jax.runtime.errors import UserError

TIPPED_DEG = 30.0
MEASURES = ("length", "step_boundary_mm", "step_inside_mm", "tilt_deg", "grasps")


def _up_axis(quat_xyzw: np.ndarray) -> np.ndarray:
  """(T, 4) xyzw quaternions -> (T, 3) the rotated z axis."""
  x, y, z, w = np.moveaxis(quat_xyzw, -1, 0)
  return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def episode_measures(ep: dict, n_action_steps: int, quat_slice: slice, num_robots: int = 1) -> dict:
  """One episode ({"actions": (T, 10 * num_robots) absolute, "obs": {"object": (T, D)}}) -> its MEASURES."""
  actions = np.asarray(ep["actions"], np.float64).reshape(len(ep["actions"]), num_robots, -1)  # (T, R, 10)
  steps = 1000 * np.linalg.norm(np.diff(actions[..., :3], axis=0), axis=-1).mean(-1)  # steps[t - 1]: a_t - a_(t-1)
  t = np.arange(1, len(actions))
  boundary = t % n_action_steps == 0
  up = _up_axis(np.asarray(ep["obs"]["object"], np.float64)[:, quat_slice])
  up /= np.linalg.norm(up, axis=-1, keepdims=True)
  tilt = np.degrees(np.arccos(np.clip(up @ up[0], -1.0, 1.0)))
  closed = actions[..., -1] > 0  # (T, R)
  grasps = int((closed[0] + (closed[1:] & ~closed[:-1]).sum(0)).max())
  mean = lambda x: round(float(x.mean()), 2) if len(x) else None  # (None: JSON has no NaN)
  return dict(
    length=len(actions),
    step_boundary_mm=mean(steps[boundary]),
    step_inside_mm=mean(steps[~boundary]),
    tilt_deg=round(float(tilt.max()), 2),
    grasps=grasps,
  )


def _quat_slice(task: str) -> slice:
  """Where the object's own orientation sits in the task's `object` vector."""
  offset = 0
  for kind, size in registry.TASKS.factory(task).object_layout:
    if kind == "quat":
      return slice(offset, offset + size)
    offset += size
  raise ValueError(f"task {task!r} has no object orientation in its observations")


def run_measures(workdir: str, r: int) -> dict:
  """{workdir, method, task, seed, round, kept: {measure: per episode}, demos: {measure: per episode}}."""
  run = rundir.RunDir.open(workdir)
  config = run.config
  if config.env.action_mode != "absolute":
    raise UserError(
      f"{workdir}: the commanded position is measured on absolute actions, not {config.env.action_mode!r}"
    )
  path = run.data_path(r)
  if not os.path.exists(path):
    raise UserError(f"{workdir}: round {r} kept nothing or has not explored yet ({path} is missing)")
  quats, ta = _quat_slice(config.env.task), int(config.policy.n_action_steps)
  arms = registry.num_robots(config.env.task)
  table = lambda eps: {k: [m[k] for m in (episode_measures(ep, ta, quats, arms) for ep in eps)] for k in MEASURES}
  return dict(
    workdir=workdir,
    method=config.method,
    task=config.env.task,
    seed=int(config.seed),
    round=r,
    kept=table(hdf5.read_episodes(path)[0]),
    demos=table(run.demonstrations()),
  )


def pooled(per_episode: dict) -> dict:
  """Per-episode measures -> episodes, mean length, mean steps, the shares tipped and re-grasped."""
  tilt, grasps = np.asarray(per_episode["tilt_deg"]), np.asarray(per_episode["grasps"])
  return dict(
    episodes=len(tilt),
    length=float(np.mean(per_episode["length"])),
    step_boundary_mm=float(np.nanmean(np.asarray(per_episode["step_boundary_mm"], float))),
    step_inside_mm=float(np.nanmean(np.asarray(per_episode["step_inside_mm"], float))),
    tipped=int((tilt > TIPPED_DEG).sum()),
    regrasped=int((grasps > 1).sum()),
  )


@dataclasses.dataclass(frozen=True)
class Kept(Study):
  round: int = setting(1, "The exploration round whose kept episodes are measured.")
  name = "kept"
  kind = "kept"
  usage = "RUN_DIR [RUN_DIR ...]"
  takes = "1+"
  compiles = False

  def run(self, paths, config=None):
    """Provenance, then `runs`: each run's `run_measures` of round `round`."""
    return dict(provenance.header(), runs=[run_measures(w, self.round) for w in paths])

  @staticmethod
  def table(committed: records.Records) -> str:
    """Per task and method the kept episodes pooled over its runs (seeds, over every record), and per
    task the demonstrations of those runs (each seed's once)."""
    runs = [run for _, r in committed for run in r["runs"]]
    groups: dict[tuple, dict] = {}
    for r in runs:
      kept = groups.setdefault((r["task"], r["method"]), {k: [] for k in MEASURES} | {"seeds": set()})
      demos = groups.setdefault((r["task"], "demonstrations"), {k: [] for k in MEASURES} | {"seeds": set()})
      for group, measured in ((kept, r["kept"]), (demos, r["demos"])):
        if r["seed"] in group["seeds"]:
          continue
        group["seeds"].add(r["seed"])
        for k in MEASURES:
          group[k] += measured[k]
    rows = []
    for (task, method), g in sorted(groups.items(), key=lambda x: (x[0][0], x[0][1] != "demonstrations", x[0][1])):
      p = pooled(g)
      share = lambda k: f"{p[k]} / {p['episodes']} ({100 * p[k] / p['episodes']:.0f}%)"
      steps = f"{p['step_boundary_mm']:.1f} / {p['step_inside_mm']:.1f}"
      rows.append([task, method, len(g["seeds"]), p["episodes"], f"{p['length']:.1f}", steps, share("tipped"),
                   share("regrasped")])  # fmt: skip
    header = ["task", "episodes of", "seeds", "episodes", "mean length (steps)",
              "position step at chunk boundaries / inside chunks (mm)", f"tipped (> {TIPPED_DEG:g}°)", "re-grasped"]  # fmt: skip
    return markdown(header, rows)

  def write(self, record, path):
    """The record as JSON, its kind first, a line per run (the per-episode lists stay on it)."""
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    result = dict(kind=self.kind, **record)
    with atomic.replacing(path) as tmp, open(tmp, "w") as f:
      f.write("{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in result.items() if k != "runs"))
      f.write(',\n"runs": [\n' + ",\n".join(json.dumps(r) for r in result["runs"]) + "\n]}\n")
