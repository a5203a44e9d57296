"""Serve a checkpoint's policy to a robot over openpi's websocket protocol (`soe_jax/serve/server.py`).

  python -m soe_jax serve --checkpoint=runs/robot/rounds/0/ckpt [--port=8000] [--host=127.0.0.1]
      [--mode=base|soe|sime|steer] [--record=DIR] [--page_port=8001]

Compiles every mode (`serve/modes.py`), then listens; the first lines printed are the address, the
page's address and the token every client must send (openpi-client: `WebsocketClientPolicy(host, port, api_key=TOKEN)`, wrapped in
`ActionChunkBroker(policy, action_horizon=Ta)` with the Ta printed). The token is random per start
unless the environment variable SOE_JAX_SERVE_TOKEN gives one. Bound to 127.0.0.1; another --host needs
--remote and prints a warning (anyone on that network who has the token can drive the robot).
Each request may name its mode (`mode` in the observation dict; --mode is the default). With --record,
episodes a person labels (from the robot's helper, `soe_jax/serve/client.py`, or on the page) are written
as a LeRobotDataset under DIR/lerobot (`serve/recorder.py`), which `refit --episodes=DIR/lerobot` takes.
The page (`serve/page.py`) shows each robot's cameras, the steering proposals to choose from and the
ended episodes to label. Ctrl-C stops it.
"""

from __future__ import annotations

import threading

from soe_jax.runtime import access, cli
from soe_jax.runtime.errors import UserError

FLAGS = cli.Flags()
FLAGS.string("checkpoint", None, "A checkpoint directory (a run's round<r>/ckpt, or what `fit` wrote).")
FLAGS.string("host", "127.0.0.1", "Address to bind (other than loopback: reachable from the network; needs --remote).")
FLAGS.boolean("remote", False, "Allow --host to be an address other than loopback.")
FLAGS.integer("port", 8000, "Port (0: any free one).", lower_bound=0)
FLAGS.integer(
  "seed",
  0,
  "Sampling seed: request n of episode e samples with session.request_key(seed, instance, e, n), where the "
  "instance is the microseconds since the epoch at start and e counts episodes over every connection.",
)
FLAGS.list("origin", [], "Browser origins allowed to connect (none by default; robots' clients send no Origin).")
FLAGS.integer("max_message_mb", 16, "Largest frame accepted, in MiB.", lower_bound=1)
FLAGS.string("mode", "base", "The mode of requests that name none: base, soe, sime or steer.")
FLAGS.string("record", None, "Write the labelled episodes under this directory (DIR/lerobot); none: not recording.")
FLAGS.string(
  "task", "", "The task's description, written with each recorded episode (default: the fitted dataset's only task)."
)
FLAGS.integer(
  "page_port", None, "The page's port (default --port + 1, any free one with --port=0; -1: no page).", lower_bound=-1
)
FLAGS.float("steer_timeout", 30.0, "Seconds a steer request waits for a choice on the page.", lower_bound=0.0)
# The exploring modes' settings; one left out is its strategy's default (`serve/modes.py`).
FLAGS.float("alpha", None, "soe's exploration scale (default: the soe strategy's).", lower_bound=0.0)
FLAGS.float("sime_scale", None, "SIME's noise scale (default: the sime strategy's; SIME's image scale for images).")
FLAGS.integer(
  "steer_dims",
  None,
  "Effective latent dimensions offered when steering, highest SNR first (default: soe_steer's max_dims, all).",
  lower_bound=1,
)
FLAGS.integer("steer_choices", None, "Proposals shown per dimension (default: soe_steer's num_choices).", lower_bound=1)


def _serve(argv: list[str]) -> None:
  cli.positional(argv, "0", "python -m soe_jax serve --checkpoint=DIR [--host=H --port=P]")
  from soe_jax.serve import modes as modes_lib
  from soe_jax.serve import page, recorder
  from soe_jax.serve.server import PolicyServer  # (websockets: the server's import only)
  from soe_jax.train import checkpoint

  if FLAGS.mode not in modes_lib.MODES:
    raise UserError(f"unknown --mode {FLAGS.mode!r}; known: {', '.join(modes_lib.MODES)}")
  try:
    loaded = checkpoint.load(FLAGS.checkpoint)
  except (FileNotFoundError, ValueError) as e:
    raise UserError(str(e)) from None
  given = dict(soe=dict(alpha=FLAGS.alpha), sime=dict(scale=FLAGS.sime_scale),
               steer=dict(max_dims=FLAGS.steer_dims, num_choices=FLAGS.steer_choices))  # fmt: skip
  given = {mode: {k: v for k, v in s.items() if v is not None} for mode, s in given.items()}
  modes = modes_lib.Modes(loaded.agent, loaded.spec, given, modes_lib.stored_snr(FLAGS.checkpoint))
  try:
    modes.check(FLAGS.mode)
  except ValueError as e:
    raise UserError(f"--mode: {e}") from None
  if FLAGS.record and not float(loaded.spec.control_hz).is_integer():
    raise UserError(f"--record: LeRobot keeps a whole number of frames per second; the policy's rate is "
                    f"{loaded.spec.control_hz:g} Hz")  # fmt: skip
  warning = access.check_bind(FLAGS.host, FLAGS.remote)
  if warning:
    print(warning, flush=True)
  token = access.new_token()
  print(f"compiling the policy of {FLAGS.checkpoint} ...", flush=True)
  try:
    rec = recorder.Recorder(FLAGS.record, loaded.spec, FLAGS.task) if FLAGS.record else None
  except recorder.LabelError as e:
    raise UserError(f"--record: {e}") from None
  server = PolicyServer(loaded.agent, loaded.spec, token, FLAGS.host, FLAGS.port, FLAGS.seed, tuple(FLAGS.origin),
                        FLAGS.max_message_mb << 20, modes, FLAGS.mode, rec, FLAGS.steer_timeout)  # fmt: skip
  print(f"serving on ws://{server.host}:{server.port} (action_horizon={loaded.policy.n_action_steps}, "
        f"{loaded.spec.control_hz:g} Hz, modes {', '.join(modes.available)}, default {FLAGS.mode}; sampling keys "
        f"seed {server.keys.seed}, instance {server.keys.instance})", flush=True)  # fmt: skip
  page_port = FLAGS.page_port if FLAGS.page_port is not None else (FLAGS.port + 1 if FLAGS.port else 0)
  if page_port >= 0:
    httpd = page.serve(server, FLAGS.host, page_port)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    print(f"page: http://{server.host}:{httpd.server_address[1]}/?token={token}", flush=True)
  print(f"token: {token}", flush=True)
  if rec is not None:
    print(f"recording labelled episodes to {rec.dataset} ({rec.saved} there already)", flush=True)
  try:
    server.serve_forever()
  finally:
    server.shutdown()  # closes the robots' connections (their threads would keep the process alive)


def main(argv: list[str] | None = None) -> None:
  cli.run(_serve, FLAGS, __doc__, argv, required=("checkpoint",), interrupted="stopped", compiles=True)
