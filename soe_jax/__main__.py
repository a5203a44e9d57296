"""`python -m soe_jax COMMAND [flags]`: every command of the project; `python -m soe_jax COMMAND --help`
prints one command's flags. A study's own name is a command too, `python -m soe_jax study NAME`'s
(`STUDY_COMMANDS`: the names launch scripts and committed records use). Listing the commands imports
nothing of JAX or MuJoCo."""

from __future__ import annotations

import importlib
import sys

# name -> what it does (each is `soe_jax/commands/<name>.py`).
COMMANDS = {
  "run": "the self-improvement experiment: round 0, then rounds of explore, keep, re-fit, evaluate",
  "compare": "exploration strategies side by side from one base policy (no re-fit)",
  "campaign": "a comparison of methods over tasks x training seeds, here or as SLURM jobs, each run copied to results/",
  "aggregate": "finished runs -> one table over tasks x methods, paired with round 0 and the control",
  "results": "committed records under results/ -> tables; --docs regenerates the documents' tables",
  "study": "measurement studies, each with its settings as flags (`study` lists them, `study NAME --help`)",
  "video": "a run's stored episodes drawn to MP4",
  "steer": "steer a run's policy by hand in a local web page",
  "fit": "a robot's policy fitted on a LeRobotDataset alone (round 0, no simulator)",
  "refit": "a robot's policy re-fitted with recorded episodes labelled successful (the next round)",
  "serve": "serve a checkpoint's policy to a robot over openpi's websocket protocol (modes, steering, recording)",
  "table1": "the paper's Table I (success, Pass@k, rollouts, jerk; before / after) from labelled robot episodes",
  "experts": "scripted demonstrations of a task, optionally saved to HDF5",
  "export": "a run's data as robomimic HDF5, Diffusion Policy zarr, RLDS or LeRobotDataset",
  "inspect": "what a data file (HDF5, zarr, RLDS, LeRobotDataset) holds",
  "bench": "performance benchmarks: env, mjx, fit, encoder, sample, rollout, torch, serve, realtime",
}
# The studies' own command names: `python -m soe_jax NAME` runs `python -m soe_jax study NAME`.
STUDY_COMMANDS = ("converge", "latent", "fidelity", "kept", "action_range", "round0", "relabel", "calibrate")


def usage() -> str:
  width = max(map(len, COMMANDS))
  lines = [f"  {name:<{width}}  {what}" for name, what in COMMANDS.items()]
  return (
    "usage: python -m soe_jax COMMAND [flags]   (COMMAND --help: its flags)\n\ncommands:\n"
    + "\n".join(lines)
    + "\n\nstudies, each also a command of its own name (python -m soe_jax NAME is python -m soe_jax study NAME):\n  "
    + ", ".join(STUDY_COMMANDS)
  )


def main(argv: list[str] | None = None) -> None:
  argv = list(sys.argv if argv is None else argv)
  if len(argv) < 2 or argv[1] in ("-h", "--help", "help"):
    print(usage())
    sys.exit(0 if len(argv) >= 2 else 2)
  name = argv[1]
  if name in STUDY_COMMANDS:
    importlib.import_module("soe_jax.commands.study").run(name, [f"python -m soe_jax {name}"] + argv[2:])
    return
  if name not in COMMANDS:
    print(f"error: unknown command {name!r}; known commands: {', '.join(COMMANDS)}", file=sys.stderr)
    sys.exit(2)
  command = importlib.import_module(f"soe_jax.commands.{name}")
  command.main([f"python -m soe_jax {name}"] + argv[2:])


if __name__ == "__main__":
  main()
