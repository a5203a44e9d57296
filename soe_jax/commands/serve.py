"""Serve a checkpoint's policy to a robot over openpi's websocket protocol (`soe_jax/serve/server.py`).

  python -m soe_jax serve --checkpoint=runs/lift-soe-seed0/round1/ckpt [--port=8000] [--host=127.0.0.1]

Compiles the policy, then listens; the first lines printed are the address and the token every client
must send (openpi-client: `WebsocketClientPolicy(host, port, api_key=TOKEN)`, wrapped in
`ActionChunkBroker(policy, action_horizon=Ta)` with the Ta printed). The token is random per start
unless the environment variable SOE_JAX_SERVE_TOKEN gives one. Bound to 127.0.0.1 unless --host says
otherwise (then with a warning: anyone on that network who has the token can drive the robot).
Ctrl-C stops it.
"""

from __future__ import annotations

import os
import secrets

from soe_jax.runtime import cli
from soe_jax.runtime.errors import UserError

TOKEN_VARIABLE = "SOE_JAX_SERVE_TOKEN"
LOOPBACK = ("127.0.0.1", "localhost", "::1")

FLAGS = cli.Flags()
FLAGS.string("checkpoint", None, "A checkpoint directory (a run's round<r>/ckpt, or what `fit` wrote).")
FLAGS.string("host", "127.0.0.1", "Address to bind (other than loopback: reachable from the network).")
FLAGS.integer("port", 8000, "Port (0: any free one).", lower_bound=0)
FLAGS.integer(
  "seed", 0, "Sampling seed: request n of a connection's episode e samples with fold_in(fold_in(seed, e), n)."
)
FLAGS.list("origin", [], "Browser origins allowed to connect (none by default; robots' clients send no Origin).")
FLAGS.integer("max_message_mb", 16, "Largest frame accepted, in MiB.", lower_bound=1)


def _serve(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax serve --checkpoint=DIR [--host=H --port=P]")
  from soe_jax.serve.server import PolicyServer  # (websockets: the server's import only)
  from soe_jax.train import checkpoint

  try:
    loaded = checkpoint.load(FLAGS.checkpoint)
  except (FileNotFoundError, ValueError) as e:
    raise UserError(str(e)) from None
  if FLAGS.host not in LOOPBACK:
    print(
      f"warning: serving on {FLAGS.host}, reachable from the network; only the token keeps strangers out", flush=True
    )
  token = os.environ.get(TOKEN_VARIABLE) or secrets.token_urlsafe(24)
  print(f"compiling the policy of {FLAGS.checkpoint} ...", flush=True)
  server = PolicyServer(loaded.agent, loaded.spec, token, FLAGS.host, FLAGS.port, FLAGS.seed, tuple(FLAGS.origin),
                        FLAGS.max_message_mb << 20)  # fmt: skip
  print(f"serving on ws://{server.host}:{server.port} (action_horizon={loaded.policy.n_action_steps}, "
        f"{loaded.spec.control_hz:g} Hz)", flush=True)  # fmt: skip
  print(f"token: {token}", flush=True)
  server.serve_forever()


def main(argv: list[str] | None = None) -> None:
  cli.run(_serve, FLAGS, __doc__, argv, required=("checkpoint",), interrupted="stopped", compiles=True)
