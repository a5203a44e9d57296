"""A run's data as robomimic HDF5, Diffusion Policy zarr, RLDS or LeRobotDataset.

  python -m soe_jax export --workdir=DIR [--round=R] --format=robomimic|zarr|rlds|lerobot --out=PATH

Exports the data the fit of round R (default: the run's last) trained on, as the loop gathers it:
the demonstrations, the episodes each round up to R kept, and the steered episodes the fit took, each
group under its own name (`demos`, `round_<r>`, `steered_<r>`; the formats: `soe_jax/data/export.py`).
`robomimic` is one HDF5 file; `zarr`, `rlds` and `lerobot` (the `zarr`, `rlds` and `robot` extras)
are directories. Prints where it wrote and the episodes of each group; `python -m soe_jax inspect PATH` reads it back.
"""

from __future__ import annotations

from soe_jax.data import export
from soe_jax.experiment.rundir import RunDir
from soe_jax.runtime import cli

FLAGS = cli.Flags()
FLAGS.string("workdir", None, "The run directory whose data is exported.")
FLAGS.integer("round", None, "The round whose fit's data is exported (default: the run's last).", lower_bound=0)
FLAGS.enum(
  "format",
  None,
  list(export.FORMATS),
  "robomimic (HDF5), zarr (Diffusion Policy's replay buffer), rlds or lerobot (LeRobotDataset v3.0).",
)
FLAGS.string("out", None, "Where the file (robomimic) or the directory (zarr, rlds, lerobot) goes.")


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax export --workdir=DIR --format=robomimic|zarr|rlds|lerobot --out=PATH")
  sets, meta = RunDir.open(FLAGS.workdir).fit_sets(FLAGS.round)
  export.write(FLAGS.out, FLAGS.format, sets, meta)
  counts = ", ".join(f"{export.group_name(s)}: {len(s.episodes)}" for s in sets)
  print(f"{FLAGS.out}: {sum(len(s.episodes) for s in sets)} episodes ({counts})")


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, required=("workdir", "format", "out"))
