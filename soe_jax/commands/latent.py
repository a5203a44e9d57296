"""The latent's SNR per dimension and its effective dimensions, and SOE's exploration from it.

  python -m soe_jax latent --config=configs/lift.py:cpu [--windows=4096] [--workdir=DIR]
      [--out=results/<study>/<name>.json]

Round 0 as `run` runs it, the SNR of each latent dimension over `--windows` observation histories of
the round-0 data and the effective dimensions (above 0 dB), then round 1's exploration exactly as
`run` runs it, so two recipes' explorations are paired episode by episode (see
`soe_jax/analysis/latent.py`). Each step is a saved phase of the workdir (default
`runs/latent/<round-0 key>-<strategy>`), so an interrupted run resumes. `--out` also writes the record
for `results/`. The last line printed is the effective dimensions and the exploration's success as one
JSON object.
"""

from __future__ import annotations

import json

from soe_jax.analysis import latent, record
from soe_jax.runtime import cli

USAGE = "python -m soe_jax latent --config=configs/<task>.py[:PRESETS] [--windows=4096]"

FLAGS = cli.Flags()
FLAGS.config_flag()
FLAGS.integer("windows", 4096, "Observation histories of the round-0 data the SNR is taken over.")
FLAGS.string("workdir", None, "Its run directory (default runs/latent/<round-0 key>-<strategy>).")
FLAGS.string("out", None, "Also write the result record (for results/) here.")
FLAGS.boolean("progress", True, "Progress bars.")


def _latent(argv: list[str]) -> None:
  cli.positional(argv, "0", USAGE)
  config = FLAGS.config
  result = latent.run(config, FLAGS.workdir, FLAGS.windows, FLAGS.progress)
  print("\n".join(latent.summary_lines(result)))
  if FLAGS.out:
    record.write_record(result, FLAGS.out, "latent")
  print(json.dumps(dict(effective_dims=result["latent"]["effective_dims"],
                        explore_success=result["explore"]["success_rate"])))  # fmt: skip


def main(argv: list[str] | None = None) -> None:
  cli.run(
    _latent,
    FLAGS,
    __doc__,
    argv,
    required=("config",),
    interrupted=cli.PHASES_SAVED,
    compiles=True,
  )
