"""Table I's numbers from a robot's labelled episodes (a LeRobotDataset the server recorded, or any
with `next.success`): per mode, the success rate with its Wilson interval, Pass@k and the rollouts to
the first success over the attempt groups (`start_state`, the tries a person made from one start
state, in recording order), and jerk at the dataset's frame rate; and the success before and after a
re-fit from two evaluation datasets, paired by start state where both name them.

A recorded episode's mode is `steer` if any of its requests steered, else the mode of its requests
(the `mode` column, an index into `serve.modes.MODES`); episodes without the column are `recorded`.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import scipy.stats

from soe_jax import metrics
from soe_jax.data import lerobot
from soe_jax.serve.modes import MODES


def episode_mode(columns: dict) -> str:
  if "mode" not in columns:
    return "recorded"
  used = {MODES[int(m)] if 0 <= int(m) < len(MODES) else f"mode {int(m)}" for m in np.unique(columns["mode"])}
  return "steer" if "steer" in used else "+".join(sorted(used))


def read(root: str, position_indices: list[list[int]] | None = None) -> dict:
  """The labelled episodes of the dataset at `root` -> {"fps", "episodes": [{index, success, mode,
  start_state (None if none), jerk}]}; positions for jerk are each arm's `position_indices` of the
  action (default: one arm, its first three numbers)."""
  info, eps = lerobot.read_dataset(root, keys=[])
  fps = float(info["fps"])
  idx = [i for i in (position_indices or [[0, 1, 2]]) if len(i) == 3]
  unlabelled = [ep["episode_index"] for ep in eps if ep["success"] is None]
  if unlabelled:
    raise lerobot.DatasetError(f"{root}: episodes {unlabelled[:5]} have no success label (next.success)")
  out = []
  for ep in eps:
    cols = ep["columns"]
    state = int(cols["start_state"][0]) if "start_state" in cols else -1
    positions = np.stack([ep["actions"][:, i] for i in idx], axis=1)  # (T, R, 3)
    out.append(dict(index=ep["episode_index"], success=bool(ep["success"]), mode=episode_mode(cols),
                    start_state=None if state < 0 else state, length=len(ep["actions"]),
                    jerk=metrics.episode_jerk(positions, dt=1.0 / fps)))  # fmt: skip
  return dict(root=root, fps=fps, episodes=out)


def groups(episodes: list[dict]) -> dict[int, list[bool]]:
  """Successes per start state, in recording order."""
  by = defaultdict(list)
  for ep in episodes:
    if ep["start_state"] is not None:
      by[ep["start_state"]].append(ep["success"])
  return dict(by)


def mode_summary(episodes: list[dict], k: int) -> dict:
  sr = metrics.success_rate([ep["success"] for ep in episodes])
  jerks = np.asarray([ep["jerk"] for ep in episodes])
  out = dict(episodes=sr["num_episodes"], successes=int(sum(ep["success"] for ep in episodes)),
             success_rate=sr["rate"], wilson=[sr["wilson_low"], sr["wilson_high"]],
             jerk_mean=float(jerks.mean()), jerk_sd=float(jerks.std(ddof=1)) if len(jerks) > 1 else 0.0)  # fmt: skip
  by = groups(episodes)
  full = {s: tries[:k] for s, tries in by.items() if len(tries) >= k}
  out.update(start_states=len(by), states_with_k_tries=len(full), k=k)
  if full:
    table = np.asarray(list(full.values()), bool)
    low, high = metrics.wilson_interval(int(table.any(axis=1).sum()), len(table))
    r = metrics.rollouts(table)
    out.update(pass_at_k=metrics.pass_at_k(table), pass_at_k_wilson=[low, high], rollouts=r["sum"],
               rollouts_mean=r["mean"])  # fmt: skip
  return out


def before_after(before: list[dict], after: list[dict]) -> dict:
  """Success before and after a re-fit: rates, the difference, the relative change, Fisher's exact p
  (unpaired), and where both name start states, the paired sign test over the shared states' success
  rates (states up against states down)."""
  b = metrics.success_rate([e["success"] for e in before])
  a = metrics.success_rate([e["success"] for e in after])
  sb, sa = sum(e["success"] for e in before), sum(e["success"] for e in after)
  _, p = scipy.stats.fisher_exact([[sa, len(after) - sa], [sb, len(before) - sb]])
  diff = a["rate"] - b["rate"]
  se = math.sqrt(a["rate"] * (1 - a["rate"]) / max(1, len(after)) + b["rate"] * (1 - b["rate"]) / max(1, len(before)))
  out = dict(before=b, after=a, difference=diff, difference_95=[diff - 1.96 * se, diff + 1.96 * se],
             relative=metrics.relative_improvement(b["rate"], a["rate"])["relative"], fisher_p=float(p))  # fmt: skip
  gb, ga = groups(before), groups(after)
  shared = sorted(set(gb) & set(ga))
  if shared:
    up = sum(np.mean(ga[s]) > np.mean(gb[s]) for s in shared)
    down = sum(np.mean(ga[s]) < np.mean(gb[s]) for s in shared)
    out["paired"] = dict(states=len(shared), up=int(up), down=int(down), sign_test_p=metrics.sign_test_p(up, down))
  return out


def table(explore: dict | None, k: int = 5, before: dict | None = None, after: dict | None = None) -> dict:
  out = dict(k=k)
  if explore is not None:
    by_mode = defaultdict(list)
    for ep in explore["episodes"]:
      by_mode[ep["mode"]].append(ep)
    out["explore"] = dict(dataset=explore["root"], fps=explore["fps"],
                          modes={m: mode_summary(eps, k) for m, eps in sorted(by_mode.items())})  # fmt: skip
  if before is not None and after is not None:
    # `before` and `after` are the two rates (before_after's); the datasets go under their own names.
    out["before_after"] = dict(before_dataset=before["root"], after_dataset=after["root"],
                               **before_after(before["episodes"], after["episodes"]))  # fmt: skip
  return out


def markdown(t: dict) -> str:
  """The table as a README would show it."""
  lines = []
  if "explore" in t:
    k = t["k"]
    lines += [f"Exploration ({t['explore']['dataset']}, jerk at {t['explore']['fps']:g} Hz):", "",
              f"| mode | episodes | success [95% CI] | Pass@{k} [95% CI] | rollouts (states with {k} tries) | jerk |",
              "|---|---|---|---|---|---|"]  # fmt: skip
    for m, s in t["explore"]["modes"].items():
      pk = (f"{s['pass_at_k']:.1%} [{s['pass_at_k_wilson'][0]:.1%}, {s['pass_at_k_wilson'][1]:.1%}]"
            if "pass_at_k" in s else "-")  # fmt: skip
      ro = f"{s['rollouts']} ({s['states_with_k_tries']})" if "rollouts" in s else f"- ({s['states_with_k_tries']})"
      lines.append(f"| {m} | {s['episodes']} | {s['success_rate']:.1%} [{s['wilson'][0]:.1%}, {s['wilson'][1]:.1%}] "
                   f"| {pk} | {ro} | {s['jerk_mean']:.3g} ± {s['jerk_sd']:.2g} |")  # fmt: skip
    lines.append("")
  if "before_after" in t:
    ba = t["before_after"]
    rel = "-" if ba["relative"] is None else f"{ba['relative']:+.0%}"
    lines += [f"Before / after the re-fit: {ba['before']['rate']:.1%} of {ba['before']['num_episodes']} -> "
              f"{ba['after']['rate']:.1%} of {ba['after']['num_episodes']} ({ba['difference']:+.1%}, 95% "
              f"[{ba['difference_95'][0]:+.1%}, {ba['difference_95'][1]:+.1%}], relative {rel}, Fisher p = "
              f"{ba['fisher_p']:.3g})"]  # fmt: skip
    if "paired" in ba:
      pr = ba["paired"]
      lines.append(f"Paired by start state: {pr['up']} up, {pr['down']} down of {pr['states']} (sign test p = "
                   f"{pr['sign_test_p']:.3g})")  # fmt: skip
  return "\n".join(lines)
