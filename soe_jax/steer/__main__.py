"""Steer a finished run's policy by hand in a local web page.

  python -m soe_jax.steer --workdir=DIR [--round=R] [--port=P] [--host=127.0.0.1]

Open the printed address (printed once the policy is compiled and the first frame rendered), pick an
effective latent dimension, click one of the proposals drawn over the scene to execute it, and save
the finished episode: it is added to the run's data as a steered episode
(`data/steered_round_<R>.hdf5`); the next round's fit takes the successful ones (all of them with
`--config.rounds.steered=all` on the run). The frames are drawn headless with EGL (another
`MUJOCO_GL` in the environment is used instead), in a process of their own (`soe_jax.render`).
"""

from __future__ import annotations

from absl import app, flags

from soe_jax import cli

flags.DEFINE_string("workdir", None, "A run directory written by python -m soe_jax.main.")
flags.DEFINE_integer("round", None, "The round whose policy to steer (default: the last finished).")
flags.DEFINE_integer("port", 8765, "Port.")
flags.DEFINE_string("host", "127.0.0.1", "Address to bind (local only by default).")
flags.DEFINE_integer("seed", 0, "Start state of the first episode.")
FLAGS = flags.FLAGS


def main(argv):
  if len(argv) > 1 or FLAGS.workdir is None:
    raise app.UsageError("usage: python -m soe_jax.steer --workdir=DIR [--round=R] [--port=P]")
  from soe_jax import compile_cache
  from soe_jax.steer import server, session

  compile_cache.enable()
  s = session.SteeringSession(FLAGS.workdir, FLAGS.round, FLAGS.seed)
  s.warm()  # compiled and first frame rendered before the address is printed
  httpd = server.serve(s, FLAGS.host, FLAGS.port)
  print(f"steering round {s.round} of {FLAGS.workdir}: http://{FLAGS.host}:{httpd.server_address[1]}/", flush=True)
  try:
    httpd.serve_forever()
  except KeyboardInterrupt:
    pass
  finally:
    httpd.server_close()
    s.close()


if __name__ == "__main__":
  cli.run(main)
