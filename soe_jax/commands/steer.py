"""Steer a finished run's policy by hand in a local web page.

  python -m soe_jax steer --workdir=DIR [--round=R] [--port=P] [--host=127.0.0.1] [--seed=S]

Open the printed address with its token (a random one per start; printed once the policy is compiled and the first frame rendered), pick an
effective latent dimension, click one of the proposals drawn over the scene to execute it, and save
the finished episode: it is added to the run's data as a steered episode
(`data/steered_round_<R>.hdf5`); the next round's fit takes the successful ones (all of them with
`--config.rounds.steered=all` on the run). The frames are drawn headless with EGL (another
`MUJOCO_GL` in the environment is used instead), in a process of their own (`soe_jax.render`).
Ctrl-C stops the server.
"""

from __future__ import annotations

from soe_jax.runtime import access, cli
from soe_jax.steer import server

FLAGS = cli.Flags()
FLAGS.string("workdir", None, "A run directory written by python -m soe_jax run.")
FLAGS.integer("round", None, "The round whose policy to steer (default: the last finished).", lower_bound=0)
FLAGS.integer("port", 8765, "Port (0: any free one).", lower_bound=0, upper_bound=65535)
FLAGS.string("host", "127.0.0.1", "Address to bind (local only by default; another needs --remote).")
FLAGS.boolean("remote", False, "Allow --host to be an address other than loopback.")
FLAGS.integer("seed", 0, "Start state of the first episode.")


def _run(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax steer --workdir=DIR [--round=R] [--port=P]")
  warning = access.check_bind(FLAGS.host, FLAGS.remote)
  if warning:
    print(warning, flush=True)
  ready = lambda session, address: print(f"steering round {session.round} of {FLAGS.workdir}: {address}", flush=True)
  server.run(FLAGS.workdir, FLAGS.round, FLAGS.seed, FLAGS.host, FLAGS.port, ready)


def main(argv: list[str] | None = None) -> None:
  cli.run(_run, FLAGS, __doc__, argv, required=("workdir",), compiles=True)
