"""A run's report (`report.md`, PNG plots, `outcomes.json`) from its `metrics.jsonl` and phase records
(`aggregate` compares many runs).

The run's row is shaped like the paper's real-world table: Pass@k, average jerk and rollouts of the
first exploration round (every method explores from the same round-0 policy and start states), the
success rate before (round 0) and after (the last round) with its episode count and 95% Wilson
interval, and the relative improvement with the absolute difference beside it. Where the repository
holds a committed campaign of the run's task and preset, the run stands beside its seeds (`context`).
"""

from __future__ import annotations

import json
import os

import numpy as np
from matplotlib.figure import Figure

from soe_jax import metrics
from soe_jax.analysis import context
from soe_jax.analysis.tables import markdown, pct, rate
from soe_jax.experiment import rundir, runlog, video
from soe_jax.runtime import atomic, faults

OUTCOMES_FILE = "outcomes.json"


def _by_phase(lines: list[dict]) -> dict:
  out = {}
  for m in lines:
    out[(m["round"], m["phase"])] = m  # a resumed run may repeat a line: the last one counts
  return out


def _round_wall_s(phases: dict, r: int) -> float:
  """Wall time of round `r`: its explore, fit and evaluate phases."""
  return sum(phases.get((r, p), {}).get("time_total_s", 0) for p in ("explore", "fit", "evaluate"))


def summarize(workdir: str) -> dict:
  """The run's numbers: method, task, seed, and the table row."""
  return _summarize(workdir)[0]


def _summarize(workdir: str) -> tuple[dict, dict]:
  """(summary, {(round, phase): metrics line})."""
  lines = runlog.read_metrics(workdir)
  if not lines:
    raise FileNotFoundError(f"{workdir} has no metrics.jsonl (not a run directory, or nothing finished yet)")
  with open(os.path.join(workdir, "config.json")) as f:
    config = json.load(f)
  phases = _by_phase(lines)
  rounds = sorted({r for r, p in phases if p == "evaluate"})
  before, after = phases.get((0, "evaluate")), phases.get((rounds[-1], "evaluate")) if rounds else None
  first = phases.get((1, "explore"))
  out = dict(
    workdir=os.path.abspath(workdir),
    task=config["env"]["task"],
    method=config["method"],
    seed=config["seed"],
    rounds=rounds,
    success_per_round=[phases[(r, "evaluate")]["success_rate"] for r in rounds],
    episodes_per_round=[phases[(r, "evaluate")]["num_rollouts"] for r in rounds],
    pass_at_k_per_round=[phases.get((r, "explore"), {}).get("pass_at_k") for r in rounds],
    rollouts_per_round=[phases.get((r, "explore"), {}).get("rollouts") for r in rounds],
  )
  walls = [_round_wall_s(phases, r) for r in rounds if r > 0]
  if walls:
    out["round_wall_s"] = float(np.mean(walls))  # one round of explore, re-fit, evaluate
  if first is not None:
    out.update(
      pass_at_k=first["pass_at_k"],
      k=first["k"],
      jerk=first["jerk"],
      rollouts=first["rollouts"],
      rollouts_mean=first["rollouts_mean"],
      kept=first["num_episodes"],  # the episodes the round added to the data
      kept_length=first.get("kept_length_mean"),  # (recorded since the length cap exists)
    )
  if before is not None:
    out["sr_before"] = before["success_rate"]
  if before is not None and after is not None and rounds[-1] > 0:  # (a round-0-only run improves on nothing)
    imp = metrics.relative_improvement(before["success_rate"], after["success_rate"])
    out.update(
      sr_after=after["success_rate"],
      sr_episodes=after["num_rollouts"],
      sr_after_wilson=(after["wilson_low"], after["wilson_high"]),
      improvement_abs=imp["absolute"],
      improvement_rel=imp["relative"],
    )
  return out, phases


def _jerk(x) -> str:
  return "-" if x is None or not np.isfinite(x) else f"{x:.1f}"


def _improvement(s: dict) -> str:
  if "improvement_abs" not in s:
    return "-"
  rel = s["improvement_rel"]
  abs_ = f"{100 * s['improvement_abs']:+.1f} pts"
  return f"undefined: 0% before ({abs_})" if rel is None else f"{100 * rel:+.1f}% ({abs_})"


def _round_wall_lines(s: dict) -> list[str]:
  """The summary's `round_wall_s`, labelled: one round's wall time."""
  if "round_wall_s" not in s:
    return []
  rounds = [r for r in s["rounds"] if r > 0]
  over = f"round {rounds[0]}" if len(rounds) == 1 else f"the mean over rounds {rounds[0]} to {rounds[-1]}"
  return [
    f"One round's wall time (explore, re-fit, evaluate; {over}): {s['round_wall_s']:.0f} s (`round_wall_s` in the "
    "summary).",
    "",
  ]


def _paired_with_round0(evaluated: dict, rounds: list[int]) -> list[str]:
  """The last round against round 0 on the same states and sampling keys (no lines if either is missing)."""
  last = str(rounds[-1]) if rounds else "0"
  if last == "0" or "0" not in evaluated or last not in evaluated:
    return []
  c = metrics.paired_comparison(evaluated["0"], evaluated[last])
  return [
    f"Paired with round 0 (the same {len(evaluated['0'])} start states and sampling keys): round {last} gained "
    f"{c['gained']} states and lost {c['lost']}, {100 * c['difference']:+.1f} points [{100 * c['low']:+.1f}, "
    f"{100 * c['high']:+.1f}], McNemar's exact p = {c['p_value']:.3g}. Against the control (the same re-fits "
    "without new data) and over seeds: `python -m soe_jax aggregate`.",
    "",
  ]


def write(workdir: str) -> dict:
  """Write `report.md`, the plots and `outcomes.json` (the per-state outcomes of every evaluation and
  exploration, `RunDir.outcomes`), each atomically (the write site "report"); return the summary."""
  with faults.site("report"):
    return _write(workdir)


def _write(workdir: str) -> dict:
  outcomes = rundir.RunDir.open(workdir).outcomes()
  atomic.write_json(os.path.join(workdir, OUTCOMES_FILE), outcomes)
  s, phases = _summarize(workdir)
  k = s.get("k", 5)
  last = s["rounds"][-1] if s["rounds"] else 0  # 0: round 0 alone, nothing after it
  after = rate(phases.get((last, "evaluate")) if last else None)
  run_row = [s["method"], pct(s.get("pass_at_k")), _jerk(s.get("jerk")), s.get("rollouts", "-"),
             rate(phases.get((0, "evaluate"))), after, _improvement(s)]  # fmt: skip
  per_round = []
  for r in s["rounds"]:
    ex, fi, ev = phases.get((r, "explore"), {}), phases.get((r, "fit"), {}), phases.get((r, "evaluate"), {})
    loss = f"{fi['final_loss']:.4f}" if fi else "-"
    per_round.append([r, rate(ev), pct(ex.get("pass_at_k")), ex.get("rollouts", "-"), _jerk(ex.get("jerk")),
                      ex.get("num_episodes", "-"), loss, f"{_round_wall_s(phases, r):.0f}"])  # fmt: skip
  md = [
    f"# {s['task']}: {s['method']} (seed {s['seed']})",
    "",
    markdown(
      [
        "Method",
        f"Pass@{k}",
        "Avg. jerk (m/s^3)",
        "Rollouts",
        "Success before",
        "Success after",
        "Relative improvement",
      ],
      [run_row],
    ),  # fmt: skip
    "Pass@k, jerk and rollouts: the first exploration round (from the shared round-0 policy). Success: the base "
    "path on the fixed evaluation start states, with its 95% Wilson interval and episode count.",
    "",
    *_round_wall_lines(s),
    *_paired_with_round0(outcomes["evaluate"], s["rounds"]),
    *context.section(workdir),
    "## Per round",
    "",
    markdown(
      ["Round", "Success", f"Pass@{k}", "Rollouts", "Jerk", "Episodes kept", "Fit loss", "Wall time (s)"], per_round
    ),  # fmt: skip
    "![success over rounds](success.png)",
    "",
  ]
  if any(p is not None for p in s["pass_at_k_per_round"]):
    md += ["![exploration over rounds](exploration.png)", ""]
  md += _video_lines(workdir, outcomes)
  atomic.write_text(os.path.join(workdir, "report.md"), "\n".join(md))
  _plots(workdir, s)
  return s


def _video_lines(workdir: str, outcomes: dict) -> list[str]:
  """Links to the run's rollout videos (`video`), a line per round and phase, each episode's outcome."""
  rounds = sorted({int(r) for phase in outcomes.values() for r in phase})
  lines = []
  for r in rounds:
    found = video.videos(workdir, r)
    for phase in video.PHASES:
      links = []
      for ph, i, rel in found:
        if ph == phase:
          done = outcomes[phase].get(str(r), [])
          links.append(f"[{i}]({rel}) {'success' if i < len(done) and done[i] else 'failure'}")
      if links:
        lines.append(f"- round {r} {phase}: " + ", ".join(links))
  if not lines:
    return []
  head = "## Videos\n\nThe first episodes of each evaluation and exploration (agent view, in-hand view beside it):\n"
  return [head, *lines, ""]


def _plots(workdir: str, s: dict) -> None:
  """success.png (success per round with Wilson intervals) and, when the run explored, exploration.png
  (rollouts and Pass@k per round)."""
  rounds = s["rounds"]
  sr = np.array(s["success_per_round"])
  n = np.array(s["episodes_per_round"])
  ci = np.array([metrics.wilson_interval(int(round(p * m)), int(m)) for p, m in zip(sr, n)]).reshape(-1, 2)
  fig = Figure(figsize=(10, 6))
  ax = fig.subplots()
  ax.errorbar(rounds, 100 * sr, yerr=100 * np.abs(ci.T - sr), marker="o", capsize=3, label="success, 95% Wilson")
  ax.set(xlabel="round", ylabel="success rate (%)", title=f"{s['task']} {s['method']}: success", xticks=rounds)
  ax.set_ylim(-3, 103)  # 0% and 100% stay off the frame
  ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1))
  fig.tight_layout()
  _save(fig, os.path.join(workdir, "success.png"))
  fig = exploration_figure(s)
  if fig is not None:  # (None: nothing explored, no exploration figure)
    _save(fig, os.path.join(workdir, "exploration.png"))


def exploration_figure(s: dict) -> Figure | None:
  """Rollouts and Pass@k per round of the summary `s` (None when no round explored)."""
  rounds = s["rounds"]
  ex_rounds = [r for r, p in zip(rounds, s["pass_at_k_per_round"]) if p is not None]
  if not ex_rounds:
    return None
  fig = Figure(figsize=(10, 6))
  ax1 = fig.subplots()
  k = s.get("k", 5)
  rollouts = [s["rollouts_per_round"][rounds.index(r)] for r in ex_rounds]
  counted = f"rollouts: each start state's tries up to its first success ({k} without one), summed over start states"
  lines = ax1.plot(ex_rounds, rollouts, "o-", color="C0", label=counted)
  ax1.set_ylim(0, 1.05 * max(rollouts))  # from 0: a constant count does not fill the axis
  ax2 = ax1.twinx()
  passes = [100 * s["pass_at_k_per_round"][rounds.index(r)] for r in ex_rounds]
  lines += ax2.plot(ex_rounds, passes, "s--", color="C1", label=f"Pass@{k}")
  ax2.set_ylabel(f"Pass@{k} (%)", color="C1")
  ax2.set_ylim(-3, 103)
  for ax, ys, fmt, color in ((ax1, rollouts, "{:.0f}", "C0"), (ax2, passes, "{:.0f}%", "C1")):  # (one round: two dots)
    for x, y in zip(ex_rounds, ys):
      ax.annotate(fmt.format(y), (x, y), textcoords="offset points", xytext=(8, 0), va="center", color=color)
  ax1.set_xticks(ex_rounds)
  ax1.legend(lines, [line.get_label() for line in lines], loc="upper center", bbox_to_anchor=(0.5, -0.1))
  ax1.set(xlabel="round", title=f"{s['task']} {s['method']}: exploration")
  ax1.set_ylabel("rollouts (sum over start states)", color="C0")
  fig.tight_layout()
  return fig


def _save(fig: Figure, path: str) -> None:
  with atomic.replacing(path, suffix=".png") as tmp:
    fig.savefig(tmp, dpi=110)
