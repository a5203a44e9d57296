"""Is round 0 converged? A fit, its in-fit evaluations and a paired continuation.

  python -m soe_jax converge --config=configs/lift.py:cpu [--eval_every=1000] [--eval_states=50]
      [--check_states=400] [--extra=0.5] [--workdir=DIR] [--out=results/<study>/<name>.json]

Round 0 as `run` runs it with its EMA policy evaluated every `--eval_every` fit steps on
`--eval_states` start states; the same fit continued for `--extra` x its steps on the same data; both
evaluated on `--check_states` paired start states (see `soe_jax/analysis/converge.py`). Each step is a
saved phase of the workdir (default `runs/converge/<task>-<round-0 hash>`), so an interrupted run
resumes. Prints the success along the fit and the check; `--out` also writes the record for
`results/`. The last line printed is the check as one JSON object.
"""

from __future__ import annotations

import json

from soe_jax.analysis import converge, record
from soe_jax.runtime import cli

USAGE = "python -m soe_jax converge --config=configs/<task>.py[:PRESETS] [flags]"

FLAGS = cli.Flags()
FLAGS.config_flag()
FLAGS.integer("eval_every", 1000, "Fit steps between in-fit evaluations.")
FLAGS.integer("eval_states", 50, "Start states of each in-fit evaluation.")
FLAGS.integer("check_states", 400, "Paired start states of the convergence check.")
FLAGS.float("extra", 0.5, "The continuation's steps, as a fraction of the fit's.")
FLAGS.string("workdir", None, "Its run directory (default runs/converge/<round-0 key>).")
FLAGS.string("out", None, "Also write the result record (for results/) here.")
FLAGS.boolean("progress", True, "Progress bars.")


def _converge(argv: list[str]) -> None:
  cli.positional(argv, "0", USAGE)
  config = FLAGS.config
  result = converge.run(config, FLAGS.workdir, FLAGS.eval_every, FLAGS.eval_states, FLAGS.check_states,
                        FLAGS.extra, FLAGS.progress)  # fmt: skip
  print("\n".join(converge.curve_lines(result)))
  if FLAGS.out:
    record.write_record(result, FLAGS.out, "converge")
  check = result["check"]
  print(json.dumps({k: check[k] for k in ("converged", "difference", "low", "high", "p_value")}))


def main(argv: list[str] | None = None) -> None:
  cli.run(
    _converge,
    FLAGS,
    __doc__,
    argv,
    required=("config",),
    interrupted=cli.PHASES_SAVED,
    compiles=True,
  )
