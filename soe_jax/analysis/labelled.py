"""Table I's numbers from a robot's labelled episodes (a LeRobotDataset the server recorded, or any
with `next.success`): per mode, the success rate with its Wilson interval, Pass@k and the rollouts to
the first success over the attempt groups (`start_state`, the tries a person made from one start
state, in recording order), and jerk at the dataset's frame rate; and the success before and after a
re-fit from two evaluation datasets, paired by start state where both name them. For several methods
(`methods_table`): each one's exploration and its evaluation after its re-fit against one shared
evaluation before, and the methods paired with each other by start state.

A recorded episode's mode is `steer` if any of its requests steered, else the mode of its requests
(the `mode` column, an index into `serve.modes.MODES`); episodes without the column are `recorded`.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter, defaultdict

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
  if (pr := paired(after, before)) is not None:
    out["paired"] = pr
  return out


def paired(a: list[dict], b: list[dict]) -> dict | None:
  """Two sets of episodes paired by start state: over the states both name, how many have a higher
  success rate in `a` than in `b` (up) and how many a lower one (down), with the two-sided sign test
  (McNemar's exact test with one try per state); None where they share no state."""
  ga, gb = groups(a), groups(b)
  shared = sorted(set(ga) & set(gb))
  if not shared:
    return None
  up = sum(np.mean(ga[s]) > np.mean(gb[s]) for s in shared)
  down = sum(np.mean(ga[s]) < np.mean(gb[s]) for s in shared)
  return dict(states=len(shared), up=int(up), down=int(down), sign_test_p=metrics.sign_test_p(up, down))


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


def methods_table(methods: dict[str, tuple[dict | None, dict | None]], k: int = 5, before: dict | None = None) -> dict:
  """The paper's Table I for several methods sharing one evaluation before the re-fit: `methods`
  {name: (its exploration episodes, its evaluation after the re-fit)} (`read`'s, either None), in the
  order to show. Per method its exploration over all the recording's episodes (`mode_summary`, with
  the modes they were recorded in) and its success after the re-fit, against `before` where given
  (`before_after`); between each pair of methods (the later named against the earlier), the paired
  sign test over the start states both name, after the re-fit and in exploration."""
  out = dict(k=k, before=None, methods={}, between=[])
  if before is not None:
    out["before"] = dict(dataset=before["root"], **metrics.success_rate([e["success"] for e in before["episodes"]]))
  for name, (explore, after) in methods.items():
    row = dict(explore=None, after=None, vs_before=None)
    if explore is not None:
      modes = dict(sorted(Counter(ep["mode"] for ep in explore["episodes"]).items()))
      row["explore"] = dict(dataset=explore["root"], fps=explore["fps"], modes=modes,
                            **mode_summary(explore["episodes"], k))  # fmt: skip
    if after is not None:
      row["after"] = dict(dataset=after["root"], **metrics.success_rate([e["success"] for e in after["episodes"]]))
      if before is not None:
        ba = before_after(before["episodes"], after["episodes"])
        row["vs_before"] = {key: v for key, v in ba.items() if key not in ("before", "after")}
    out["methods"][name] = row
  names = list(methods)
  for i, j in itertools.combinations(range(len(names)), 2):
    (ea, aa), (eb, ab) = methods[names[j]], methods[names[i]]
    both = lambda x, y: paired(x["episodes"], y["episodes"]) if x is not None and y is not None else None
    pair = dict(a=names[j], b=names[i], after=both(aa, ab), explore=both(ea, eb))
    if pair["after"] is not None or pair["explore"] is not None:
      out["between"].append(pair)
  return out


def _rate(r: dict | None) -> str:
  """A success rate with its Wilson interval."""
  return "-" if r is None else f"{r['rate']:.1%} [{r['wilson_low']:.1%}, {r['wilson_high']:.1%}]"


def _pair(pr: dict) -> str:
  return f"{pr['up']} up, {pr['down']} down of {pr['states']} (sign test p = {pr['sign_test_p']:.3g})"


def methods_markdown(t: dict) -> str:
  """`methods_table` as a README would show it: one row per method, then the paired tests."""
  k, before = t["k"], t["before"]
  lines = []
  if before is not None:
    lines.append(f"Before the re-fit ({before['dataset']}): {_rate(before)} of {before['num_episodes']}")
  fps = sorted({row["explore"]["fps"] for row in t["methods"].values() if row["explore"] is not None})
  jerk = f"jerk ({', '.join(f'{f:g}' for f in fps)} Hz)" if fps else "jerk"
  lines += ["", f"| method | explored | success [95% CI] | Pass@{k} [95% CI] | rollouts (states with {k} tries) "
            f"| {jerk} | success after [95% CI] | change [95% CI] | relative | Fisher p | vs before, paired by state |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
  notes = []
  for name, row in t["methods"].items():
    e, a, vb = row["explore"], row["after"], row["vs_before"]
    cells = [name]
    if e is None:
      cells += ["-"] * 5
    else:
      pk = (f"{e['pass_at_k']:.1%} [{e['pass_at_k_wilson'][0]:.1%}, {e['pass_at_k_wilson'][1]:.1%}]"
            if "pass_at_k" in e else "-")  # fmt: skip
      ro = f"{e['rollouts']} ({e['states_with_k_tries']})" if "rollouts" in e else f"- ({e['states_with_k_tries']})"
      cells += [str(e["episodes"]), f"{e['success_rate']:.1%} [{e['wilson'][0]:.1%}, {e['wilson'][1]:.1%}]", pk, ro,
                f"{e['jerk_mean']:.3g} ± {e['jerk_sd']:.2g}"]  # fmt: skip
      if len(e["modes"]) > 1:
        each = ", ".join(f"{m} {n}" for m, n in e["modes"].items())
        notes.append(f"{name}'s exploration ({e['dataset']}) pools episodes of several modes: {each}")
    cells.append("-" if a is None else f"{_rate(a)} of {a['num_episodes']}")
    if vb is None:
      cells += ["-"] * 4
    else:
      rel = "-" if vb["relative"] is None else f"{vb['relative']:+.0%}"
      lo, hi = vb["difference_95"]
      cells += [f"{vb['difference']:+.1%} [{lo:+.1%}, {hi:+.1%}]", rel, f"{vb['fisher_p']:.3g}",
                _pair(vb["paired"]) if "paired" in vb else "-"]  # fmt: skip
    lines.append("| " + " | ".join(cells) + " |")
  if t["between"]:
    lines += ["", "Between methods, paired by start state (the states both name; each state's success rate):"]
    for pr in t["between"]:
      for what, label in (("after", "after the re-fit"), ("explore", "exploration")):
        if pr[what] is not None:
          lines.append(f"- {label}, {pr['a']} against {pr['b']}: {_pair(pr[what])}")
  lines += [""] + notes if notes else []
  return "\n".join(lines).lstrip("\n")
