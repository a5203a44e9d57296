"""Re-fit a robot's policy with the episodes of a recorded LeRobotDataset labelled successful (the next
round; no simulator).

  python -m soe_jax refit --workdir=runs/robot --episodes=RECORDED [--mode=continue|scratch]

Takes every episode whose last frame has `next.success` true (`refit.select` of the run's config:
`first_success` keeps the first per start state and needs a `start_state` column), adds them to the
demonstrations and the episodes earlier rounds took, and fits round r+1 (`refit.mode`: continue from
round r's parameters, or from scratch), writing `rounds/<r+1>/ckpt`. Run the same command again to
resume a stopped re-fit. The last line printed is the round's record as JSON.
"""

from __future__ import annotations

import json

from soe_jax.runtime import cli

FLAGS = cli.Flags()
FLAGS.string("workdir", "runs/robot", "The robot run (what `fit` wrote).")
FLAGS.string("episodes", None, "The LeRobotDataset of recorded episodes, with success labels (next.success).")
FLAGS.enum("mode", None, ["continue", "scratch"], "Override the run's refit.mode.")
FLAGS.boolean("progress", True, "Progress bars.")


def _refit(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax refit --workdir=DIR --episodes=RECORDED")
  from soe_jax.robot import run  # (after the flags: --help imports nothing of JAX)

  record = run.refit(FLAGS.workdir, FLAGS.episodes, FLAGS.progress, FLAGS.mode)
  print(json.dumps({k: v for k, v in record.items() if k != "loss_curve"}))


def main(argv: list[str] | None = None) -> None:
  cli.run(_refit, FLAGS, __doc__, argv, required=("episodes",),
          interrupted="interrupted: the re-fit is saved; run the same command to resume", compiles=True)  # fmt: skip
