"""What a round kept, episode by episode, against the demonstrations the run started from.

  python -m soe_jax.kept RUN_DIR [RUN_DIR ...] [--round=1] [--out=results/<study>/<name>.json]

For each run (a workdir of `main` or of a campaign), the episodes round `--round`'s exploration kept
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
Printed as a table with a row per run (episodes pooled) and a row of the run's demonstrations; `--out`
writes the record (command, commit, machine, and per run its method, seed and per-episode numbers;
the runs' configs are in their workdirs) for `results/`, where `python -m soe_jax.results` tables it.
"""

from __future__ import annotations

import json
import os

import numpy as np
from absl import app, flags

from soe_jax import cli

FLAGS = flags.FLAGS


def define_flags() -> None:
  """The command's flags, defined only when it runs (`results` imports its table beside other
  commands' flags)."""
  flags.DEFINE_integer("round", 1, "The exploration round whose kept episodes are measured.")
  flags.DEFINE_string("out", None, "Also write the record (for results/) here.")


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
  from soe_jax.envs import registry

  offset = 0
  for kind, size in registry.TASKS.factory(task).object_layout:
    if kind == "quat":
      return slice(offset, offset + size)
    offset += size
  raise ValueError(f"task {task!r} has no object orientation in its observations")


def run_measures(workdir: str, r: int) -> dict:
  """{workdir, method, task, seed, round, kept: {measure: per episode}, demos: {measure: per episode}}."""
  from soe_jax import rundir
  from soe_jax.data import hdf5
  from soe_jax.envs import registry
  from soe_jax.errors import UserError

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


def table(runs: list[dict]) -> str:
  """Per task and method the kept episodes pooled over its runs (seeds), and per task the
  demonstrations of those runs (each seed's once)."""
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
  md = ["| task | episodes of | seeds | episodes | mean length (steps) | position step at chunk boundaries / inside "
        f"chunks (mm) | tipped (> {TIPPED_DEG:g}°) | re-grasped |",
        "|---|---|---|---|---|---|---|---|"]  # fmt: skip
  for (task, method), g in sorted(groups.items(), key=lambda x: (x[0][0], x[0][1] != "demonstrations", x[0][1])):
    p = pooled(g)
    share = lambda k: f"{p[k]} / {p['episodes']} ({100 * p[k] / p['episodes']:.0f}%)"
    md.append(
      f"| {task} | {method} | {len(g['seeds'])} | {p['episodes']} | {p['length']:.1f} | "
      f"{p['step_boundary_mm']:.1f} / {p['step_inside_mm']:.1f} | {share('tipped')} | {share('regrasped')} |"
    )
  return "\n".join(md) + "\n"


def main(argv):
  from soe_jax import provenance

  if len(argv) < 2:
    raise app.UsageError("usage: python -m soe_jax.kept RUN_DIR [RUN_DIR ...] [--round=1] [--out=FILE.json]")
  record = dict(provenance.header(), runs=[run_measures(w, FLAGS.round) for w in argv[1:]])
  print(table(record["runs"]), end="")
  if FLAGS.out:
    os.makedirs(os.path.dirname(FLAGS.out) or ".", exist_ok=True)
    with open(FLAGS.out, "w") as f:  # a line per run: the per-episode lists stay on it
      f.write("{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in record.items() if k != "runs"))
      f.write(',\n"runs": [\n' + ",\n".join(json.dumps(r) for r in record["runs"]) + "\n]}\n")
    print(f"-> {FLAGS.out}")


if __name__ == "__main__":
  define_flags()
  cli.run(main)
