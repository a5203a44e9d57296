"""`python -m soe_jax.main`: the run command's older name (`python -m soe_jax run`), which committed
records and documents name."""

import sys

from soe_jax.commands import run

if __name__ == "__main__":
  run.main(["python -m soe_jax.main"] + sys.argv[1:])
