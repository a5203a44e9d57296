"""A run's stored episodes drawn to MP4 again.

  python -m soe_jax video --workdir=DIR [--round=R] [--size=256]

Draws the episodes each evaluation and exploration phase stored (its first `log.videos`) from the agent
view with the in-hand view beside it, at the control rate, into `DIR/videos/round_<r>_<phase>_<i>.mp4`,
and prints each path as it is written: round R's, or every round's without --round (files already
there are drawn again). A run draws each round's videos as it finishes; this is for afterwards.
"""

from __future__ import annotations

from soe_jax.experiment import video
from soe_jax.runtime import cli

FLAGS = cli.Flags()
FLAGS.string("workdir", None, "The run directory.")
FLAGS.integer("round", None, "The round to draw (default: every round with stored episodes).", lower_bound=0)
FLAGS.integer("size", video.SIZE, "Pixels per camera view (height and width).", lower_bound=1)


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax video --workdir=DIR [--round=R] [--size=256]")
  for path in video.render_run(FLAGS.workdir, FLAGS.round, FLAGS.size):
    print(path, flush=True)


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, required=("workdir",))
