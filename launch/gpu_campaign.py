"""One seed of the one-round comparison on a GPU host: physics in the C engine on the host's CPUs,
the policy's fits and sampling on the GPU, the same config as the CPU campaign's (`configs/<task>.py:cpu`),
so its figures stand beside the CPU's from `results/campaign-cpu/<task>/seed<k>/`.

  python launch/gpu_campaign.py [--task=lift] [--seed=0] [--budget=290] [--cap=150]
      [--methods=soe,dp,control,sime,soe_steer] [--presets=cpu] [--out=DIR]

Each method is one `python -m soe_jax campaign` process with its own time cap (the first also fits round
0), run in order until the budget is spent. After each, DIR/campaign.md (each case's status and
wall time, then the campaign's comparison table), DIR/campaign.png (success before and after, and the
time of each phase, per method, GPU beside CPU) and DIR/results/ (the campaign's `results/` files) are
rewritten, so a run cut short keeps what it measured. `--presets=smoke` checks the script on a CPU in
minutes.
"""

from __future__ import annotations

import argparse
import os

from gpu_physics import command, pyplot, run_all  # (launch/ is the script's directory)

from soe_jax.experiment import runlog

PHASES = (("0", "fit"), ("1", "explore"), ("1", "fit"), ("1", "evaluate"))
MODULE = "soe_jax"  # each case is `python -m soe_jax campaign ...`


def cases(task: str, seed: int, methods: list[str], presets: str, out: str) -> list[tuple[str, list[str]]]:
  """[(case name, the arguments after `python -m MODULE`)], one case per method."""
  common = ["campaign", f"--config=configs/{task}.py:{presets}", "--config.env.backend=mujoco"]
  common += ["--config.log.videos=0", f"--config.seed={seed}"]  # (no videos: their encoder need not be on the host)
  common += [f"--workdir={out}/runs", f"--results={out}/results", "--progress=false"]
  return [(f"{task} seed {seed} {m}", [*common, f"--methods={m}"]) for m in methods]


def command_lines(task: str, seed: int, methods: list[str], presets: str, out: str) -> list[list[str]]:
  """The subprocesses' argv, in order, as `gpu_physics.run_case` starts them."""
  return [command(args, MODULE) for _, args in cases(task, seed, methods, presets, out)]


def metrics(run_dir: str) -> dict | None:
  """{(round, phase): record} of a run's metrics.jsonl (None if it has none yet)."""
  return {(str(r["round"]), r["phase"]): r for r in runlog.read_metrics(run_dir)} or None


def write(out: str, task: str, seed: int, methods: list[str], records: list[dict], left: list[str]) -> None:
  md = ["| case | status | wall s |", "|---|---|---|"]
  md += [f"| {r['case']} | {r['status']} | {r['wall_s']} |" for r in records]
  md += [f"| {c} | not run (budget) | |" for c in left]
  comparison = os.path.join(out, "results", "comparison.md")
  if os.path.exists(comparison):
    with open(comparison) as f:
      md += ["", f.read()]
  with open(os.path.join(out, "campaign.md"), "w") as f:
    f.write("\n".join(md) + "\n")
  plt = pyplot()
  if plt is None:
    return
  where = {"GPU": os.path.join(out, "results"), "CPU": os.path.join("results", "campaign-cpu")}
  runs = {(m, w): metrics(os.path.join(d, task, f"seed{seed}", m)) for m in methods for w, d in where.items()}
  fig, (ax_sr, ax_t) = plt.subplots(1, 2, figsize=(11, 4))
  width = 0.2
  for i, m in enumerate(methods):
    for j, w in enumerate(where):
      r = runs[(m, w)]
      if r is None:
        continue
      x = i + (j - 0.5) * 2 * width
      before, after = (r.get((k, "evaluate"), {}).get("success_rate") for k in ("0", "1"))
      ax_sr.bar(x - width / 2, before or 0, width, color=f"C{j}", alpha=0.4)
      ax_sr.bar(x + width / 2, after or 0, width, color=f"C{j}", label=w if i == 0 else None)
      bottom = 0.0
      for k, (rnd, phase) in enumerate(PHASES):
        t = r.get((rnd, phase), {}).get("time_total_s") or 0.0
        ax_t.bar(
          x, t, 2 * width, bottom=bottom, color=f"C{k + 2}", label=f"round {rnd} {phase}" if i == j == 0 else None
        )
        bottom += t
      ax_t.text(x, bottom, w, ha="center", va="bottom", fontsize=7)
  for ax in (ax_sr, ax_t):
    ax.set_xticks(range(len(methods)), methods)
  ax_sr.set(ylabel="success (light: round 0, dark: after round 1)", ylim=(0, 1), title=f"{task}, seed {seed}")
  ax_t.set(ylabel="seconds (compile included)", title="time per phase")
  for ax, size in ((ax_sr, 8), (ax_t, 7)):
    if ax.get_legend_handles_labels()[0]:  # (nothing finished yet: no legend)
      ax.legend(fontsize=size)
  fig.tight_layout()
  fig.savefig(os.path.join(out, "campaign.png"), dpi=120)
  plt.close(fig)


def main() -> None:
  parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
  parser.add_argument("--task", default="lift")
  parser.add_argument("--seed", type=int, default=0)
  parser.add_argument("--methods", default="soe,dp,control,sime,soe_steer", help="in order of priority")
  parser.add_argument("--presets", default="cpu", help="the presets of configs/<task>.py (the CPU campaign's)")
  parser.add_argument("--budget", type=float, default=290, help="seconds for all cases together")
  parser.add_argument("--cap", type=float, default=150, help="seconds for one case (the first fits round 0 too)")
  parser.add_argument("--out", default="gpu-campaign")
  a = parser.parse_args()
  os.makedirs(a.out, exist_ok=True)
  methods = a.methods.split(",")
  todo = cases(a.task, a.seed, methods, a.presets, a.out)
  run_all(
    todo,
    a.budget,
    a.cap,
    lambda records, left: write(a.out, a.task, a.seed, methods, records, left),
    MODULE,
  )


if __name__ == "__main__":
  main()
