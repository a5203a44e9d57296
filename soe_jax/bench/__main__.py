"""Benchmarks, each printing one JSON object as its last line.

python -m soe_jax.bench env --task=square --num_envs=256 [--backend=mujoco|mjx --mjx_impl=jax|warp] [--num_envs=1 --unbatched]
    [--obs_mode=image --renderer=auto|gl|warp] [--out=results/render/<name>.json]
python -m soe_jax.bench mjx --task=lift --mjx_impl=warp --num_envs=200 [--out=results/mjx/lift-warp.json]
python -m soe_jax.bench fit --config=configs/square.py [--bypass=on|off] [--ema=on|off]
python -m soe_jax.bench encoder [--batch=64 --widths=64,128,256,512] [--out=results/encoder/<name>.json]
python -m soe_jax.bench sample --config=configs/square.py --batch=1 --steps=10
python -m soe_jax.bench rollout --config=configs/lift.py:cpu --strategy=soe --num_envs=100
python -m soe_jax.bench converge --config=configs/lift.py:cpu [--eval_every=1000 --eval_states=50
    --check_states=400 --extra=0.5 --workdir=DIR --out=results/<study>/<name>.json]
python -m soe_jax.bench latent --config=configs/lift.py:cpu [--windows=4096 --workdir=DIR --out=FILE]
"""

from __future__ import annotations

import json

from absl import app, flags
from ml_collections import config_flags

from soe_jax import cli

flags.DEFINE_string("task", "lift", "Task name (env).")
flags.DEFINE_integer("num_envs", 64, "Batch of environments (env, rollout; mjx: demonstrations).")
flags.DEFINE_string("backend", "auto", "Physics backend: auto, mujoco or mjx (env).")
flags.DEFINE_string("mjx_impl", "auto", "env / mjx: MJX's implementation, auto, jax or warp.")
flags.DEFINE_string("mjx_settings", "", "env / mjx: MJX's solver options ('' the task's, engine, or name=value,...).")
flags.DEFINE_bool("unbatched", False, "env: one environment stepped without vmap.")
flags.DEFINE_string("obs_mode", "low_dim", "env: observations, low_dim or image (both cameras drawn every step).")
flags.DEFINE_string("renderer", "auto", "env: what draws the cameras, auto, gl or warp (env.renderer).")
flags.DEFINE_integer(
  "steps",
  None,
  "env: control steps per compiled call (default 20 mujoco, 2 mjx); "
  "fit: SGD steps per timed chunk (default 10; encoder 3); sample: denoising steps (default 10); "
  "rollout: decisions per timed call (default 2).",
)
flags.DEFINE_integer("repeats", None, "Timed calls.")
flags.DEFINE_enum("bypass", "off", ["on", "off"], "fit: train the VIB bypass too.")
flags.DEFINE_enum("ema", "off", ["on", "off"], "fit: keep the EMA of parameters.")
flags.DEFINE_integer("batch", 1, "sample: observations per chunk; encoder: batch size (default 64).")
flags.DEFINE_list("widths", ["64", "128", "256", "512"], "encoder: the ResNet-18 trunk's stem and stage channels.")
flags.DEFINE_string(
  "strategy",
  "",
  "rollout: exploration strategy (dp, sime, soe, soe_steer, expert; default the config's, with its settings).",
)
flags.DEFINE_integer("eval_every", 1000, "converge: fit steps between in-fit evaluations.")
flags.DEFINE_integer("eval_states", 50, "converge: start states of each in-fit evaluation.")
flags.DEFINE_integer("check_states", 400, "converge: paired start states of the convergence check.")
flags.DEFINE_float("extra", 0.5, "converge: the continuation's steps, as a fraction of the fit's.")
flags.DEFINE_integer("windows", 4096, "latent: observation histories of the round-0 data the SNR is taken over.")
flags.DEFINE_string(
  "workdir", None, "converge / latent: its run directory (default runs/<benchmark>/<round-0 key>...)."
)
flags.DEFINE_string(
  "out", None, "env / encoder / mjx / converge / latent: also write the result record (for results/) here."
)
flags.DEFINE_bool("progress", True, "mjx / converge / latent: progress bars.")
config_flags.DEFINE_config_file(
  "config", None, "fit / sample / rollout / converge / latent: configs/<task>.py[:PRESETS].", lock_config=True
)
FLAGS = flags.FLAGS

BENCHMARKS = ("env", "mjx", "fit", "encoder", "sample", "rollout", "converge", "latent")


def main(argv):
  if len(argv) != 2 or argv[1] not in BENCHMARKS:
    raise app.UsageError(f"usage: python -m soe_jax.bench <{'|'.join(BENCHMARKS)}> [flags]; got {argv[1:]}")
  from soe_jax import compile_cache, sharding

  compile_cache.enable()
  sharding.maybe_initialize_distributed()
  what = argv[1]
  if what in ("fit", "sample", "rollout", "converge", "latent") and FLAGS.config is None:
    raise app.UsageError(f"bench {what} needs --config=configs/<task>.py[:PRESETS]")
  if what in ("env", "encoder"):
    from soe_jax import provenance

    source = provenance.header()
  if what == "env":
    from soe_jax.bench import env

    result = env.run(
      FLAGS.task,
      FLAGS.num_envs,
      FLAGS.backend,
      FLAGS.steps,
      FLAGS.repeats or 3,
      FLAGS.unbatched,
      FLAGS.mjx_impl,
      FLAGS.mjx_settings,
      FLAGS.obs_mode,
      FLAGS.renderer,
    )
    if FLAGS.out:
      from soe_jax.bench import experiment

      experiment.write_record(dict(source, throughput=result), FLAGS.out)
  elif what == "mjx":
    from soe_jax.bench import experiment, mjx

    result = mjx.run(FLAGS.task, FLAGS.mjx_impl, FLAGS.num_envs, FLAGS.mjx_settings, progress=FLAGS.progress)
    if FLAGS.out:
      experiment.write_record(result, FLAGS.out)
    result = result["mjx"]
  elif what == "fit":
    from soe_jax.bench import policy

    result = policy.fit(FLAGS.config, FLAGS.bypass == "on", FLAGS.ema == "on", FLAGS.steps or 10, FLAGS.repeats or 2)
  elif what == "encoder":
    from soe_jax.bench import encoder

    batch = FLAGS.batch if FLAGS["batch"].present else 64
    result = encoder.run(batch, widths=tuple(int(w) for w in FLAGS.widths), steps=FLAGS.steps or 3,
                         repeats=FLAGS.repeats or 2)  # fmt: skip
    if FLAGS.out:
      from soe_jax.bench import experiment

      experiment.write_record(dict(source, encoder=result), FLAGS.out)
  elif what == "converge":
    from soe_jax.bench import converge, experiment

    result = converge.run(FLAGS.config, FLAGS.workdir, FLAGS.eval_every, FLAGS.eval_states, FLAGS.check_states,
                          FLAGS.extra, FLAGS.progress)  # fmt: skip
    print("\n".join(converge.curve_lines(result)))
    if FLAGS.out:
      experiment.write_record(result, FLAGS.out)
    result = dict(
      converged=result["check"]["converged"],
      **{k: result["check"][k] for k in ("difference", "low", "high", "p_value")},
    )
  elif what == "latent":
    from soe_jax.bench import experiment, latent

    result = latent.run(FLAGS.config, FLAGS.workdir, FLAGS.windows, FLAGS.progress)
    print("\n".join(latent.summary_lines(result)))
    if FLAGS.out:
      experiment.write_record(result, FLAGS.out)
    result = dict(effective_dims=result["latent"]["effective_dims"], explore_success=result["explore"]["success_rate"])
  elif what == "rollout":
    from soe_jax.bench import rollout

    result = rollout.run(FLAGS.config, FLAGS.strategy, FLAGS.num_envs, FLAGS.steps or 2, FLAGS.repeats or 3)
  else:
    from soe_jax.bench import policy

    result = policy.sample(FLAGS.config, FLAGS.batch, FLAGS.steps or 10, FLAGS.repeats or 20)
  print(json.dumps(result))


if __name__ == "__main__":
  cli.run(main)
