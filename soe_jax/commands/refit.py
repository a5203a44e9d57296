"""Re-fit a robot's policy with the episodes of a recorded LeRobotDataset labelled successful (the next
round; no simulator).

  python -m soe_jax refit --workdir=runs/robot --episodes=RECORDED [--mode=continue|scratch]
      [--config.rounds.refit_steps=1000 ...] [--episode_modes=soe]

Takes every episode whose last frame has `next.success` true (`rounds.select` of the run's config:
`first_success` keeps the first per start state and needs a `start_state` column), adds them to the
demonstrations and the episodes earlier rounds took, and fits round r+1 (`rounds.refit`: continue from
round r's parameters, or from scratch), writing `rounds/<r+1>/ckpt`. `--config.rounds.<field>=V`
overrides one of the run's re-fit fields (those of `rounds` in its config.json: select, refit,
refit_steps, refit_lr, refit_ema, demo_fraction, aligned_windows; a run fitted before they were named
so takes its old `refit.<field>` names too) for this round; the round's fit.json records the
overrides and the fields it used.
`--episode_modes` keeps the episodes recorded in those modes (base, soe, sime, steer; recorded: a
dataset without a mode column); without it every mode's are taken, with a warning when the recording
mixes modes. Run the same command again to resume a stopped re-fit. The last line printed is the
round's record as JSON.
"""

from __future__ import annotations

import functools
import json
import sys

import ml_collections
from absl import flags
from ml_collections import config_flags

from soe_jax.runtime import cli
from soe_jax.runtime.errors import UserError

OVERRIDE = "--config."

FLAGS = cli.Flags()
FLAGS.string("workdir", "runs/robot", "The robot run (what `fit` wrote).")
FLAGS.string("episodes", None, "The LeRobotDataset of recorded episodes, with success labels (next.success).")
FLAGS.enum("mode", None, ["continue", "scratch"], "Override the run's rounds.refit.")
FLAGS.list("episode_modes", [], "Take only the episodes recorded in these modes (default: every mode's).")
FLAGS.boolean("progress", True, "Progress bars.")


def overrides(args: list[str], rounds: ml_collections.ConfigDict) -> dict:
  """`--config.rounds.<field>=V` arguments (or a field's old name, `robot.config.RENAMED`) ->
  {"rounds.<field>": V}, each V parsed as the run's field (UserError for a field the run's `rounds`
  section does not have, or a value that is not its type)."""
  from soe_jax.robot.config import upgrade_field

  fields = sorted(f"rounds.{k}" for k in rounds)
  renamed = []
  for arg in args:
    name, _, value = arg[len(OVERRIDE) :].partition("=")
    name = upgrade_field(name)
    if name not in fields:
      raise UserError(f"{name}: not a re-fit field of the run; its re-fit fields: {', '.join(fields)}")
    renamed.append(f"{OVERRIDE}{name}={value}")
  argv = ["refit", *renamed]
  values = flags.FlagValues()
  try:
    config = ml_collections.ConfigDict(dict(rounds=rounds.to_dict()))
    config_flags.DEFINE_config_dict("config", config, flag_values=values, sys_argv=argv)
    values(argv)
  except (flags.Error, ValueError, TypeError, KeyError, AttributeError) as e:
    raise UserError(cli.message(e)) from None
  return config_flags.get_override_values(values["config"])


def _refit(argv: list[str], config_args: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax refit --workdir=DIR --episodes=RECORDED")
  from soe_jax.robot import run  # (after the flags: --help imports nothing of JAX)

  given = overrides(config_args, run.saved_config(FLAGS.workdir).rounds) if config_args else {}
  record = run.refit(FLAGS.workdir, FLAGS.episodes, FLAGS.progress, FLAGS.mode, given, FLAGS.episode_modes or None)
  print(json.dumps({k: v for k, v in record.items() if k != "loss_curve"}))


def main(argv: list[str] | None = None) -> None:
  argv = list(sys.argv if argv is None else argv)
  # `--config.rounds.<field>=V` is parsed against the run's saved config, which only the workdir names.
  config_args = [a for a in argv[1:] if a.startswith(OVERRIDE)]
  rest = [a for i, a in enumerate(argv) if not (i and a.startswith(OVERRIDE))]
  cli.run(functools.partial(_refit, config_args=config_args), FLAGS, __doc__, rest, required=("episodes",),
          interrupted="interrupted: the re-fit is saved; run the same command to resume", compiles=True)  # fmt: skip
