"""What a data file holds.

  python -m soe_jax inspect PATH

PATH: a robomimic HDF5 file (this project's demonstrations, a round's kept episodes, an export, or
robomimic's own), or an exported zarr store, RLDS dataset or LeRobotDataset (a LeRobotDataset needs
the `robot` extra). Prints the episodes per group (filter key, or source round), their lengths, every
key with its shape and dtype, and the provenance the file records.
"""

from __future__ import annotations

from soe_jax.data import inspect
from soe_jax.runtime import cli
from soe_jax.runtime.errors import UserError

FLAGS = cli.Flags()


def _run(argv: list[str]) -> None:
  (path,) = cli.positional(argv, "1", "python -m soe_jax inspect PATH")
  try:
    described = inspect.describe(path)
  except UserError:  # (a ValueError too)
    raise
  except (OSError, ValueError) as e:  # not a file of episodes (h5py's OSError, the readers' ValueError)
    raise cli.UsageError(f"{path}: not HDF5, zarr, RLDS or LeRobotDataset episodes: {cli.message(e)}") from None
  print(described, end="")


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv)
