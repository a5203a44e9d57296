"""Fit a robot's policy on a LeRobotDataset of demonstrations alone (round 0; no simulator).

  python -m soe_jax fit --config=configs/robot.py:cpu --config.dataset.path=DATA [--workdir=runs/robot]

Writes `<workdir>/rounds/0/ckpt` (serve it with `python -m soe_jax serve --checkpoint=...`), its record
`rounds/0/fit.json`, the config and the spec (`spec.json`: what the policy reads and writes). Everything
is checked before anything is written; run the same command again to resume a stopped fit. The last
line printed is the record as JSON.
"""

from __future__ import annotations

import json

from soe_jax.runtime import cli, configfile

FLAGS = cli.Flags()
FLAGS.config_flag("configs/robot.py[:PRESETS] (a robot's config: soe_jax/robot/config.py)")
FLAGS.string("workdir", "runs/robot", "Where the run goes.")
FLAGS.boolean("progress", True, "Progress bars.")


def _fit(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax fit --config=configs/robot.py[:PRESETS] --config.dataset.path=DATA")
  from soe_jax.robot import run  # (after the flags: --help imports nothing of JAX)

  spec, overrides = FLAGS.config_file()
  config = configfile.load(spec, None, overrides)
  record = run.fit(config, FLAGS.workdir, FLAGS.progress)
  print(json.dumps({k: v for k, v in record.items() if k != "loss_curve"}))


def main(argv: list[str] | None = None) -> None:
  cli.run(_fit, FLAGS, __doc__, argv, required=("config",),
          interrupted="interrupted: the fit is saved; run the same command to resume", compiles=True)  # fmt: skip
