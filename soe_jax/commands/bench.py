"""Performance benchmarks, each printing one JSON object as its last line.

  python -m soe_jax bench SUB [flags]   (SUB --help: its flags)

  python -m soe_jax bench env --task=square --num_envs=256 [--backend=mujoco|mjx --mjx_impl=jax|warp]
      [--num_envs=1 --unbatched] [--obs_mode=image --renderer=auto|gl|warp] [--out=results/render/<name>.json]
  python -m soe_jax bench mjx --task=lift --mjx_impl=warp --num_envs=200 [--out=results/mjx/lift-warp.json]
  python -m soe_jax bench fit --config=configs/square.py [--bypass=on|off] [--ema=on|off]
      [--out=results/<study>/<name>.json]
  python -m soe_jax bench encoder [--batch=64 --widths=64,128,256,512 --frames=2 --image_size=84 --crop=76 --shared]
      [--out=results/encoder/<name>.json]
  python -m soe_jax bench sample --config=configs/square.py --batch=1 --steps=10
  python -m soe_jax bench rollout --config=configs/lift.py:cpu --strategy=soe --num_envs=100
  python -m soe_jax bench torch --down_dims=256,512,1024 --step_embed_dim=256 --batch=256
  python -m soe_jax bench serve --config=configs/lift.py:cpu [--requests=200] [--camera_size=216,288]
      [--out=results/serve/<name>.json]
  python -m soe_jax bench realtime --checkpoint=RUN/round0/<name>/ckpt [--rates=10,30 --delay_ms=50 --states=50]
      [--out=results/realtime/<name>.json]

Each benchmark has flags of its own; `--out` (env, mjx, encoder, serve, realtime) also writes the result as a record
for `results/`, with the command, the commit and the machine.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from collections.abc import Callable

from soe_jax.analysis import records
from soe_jax.bench import encoder, env, mjx, policy, rollout, torch_reference
from soe_jax.bench import realtime as realtime_bench
from soe_jax.bench import serve as serve_bench
from soe_jax.envs import backends, observations
from soe_jax.envs import registry as env_registry
from soe_jax.experiment import rundir
from soe_jax.experts import registry as expert_registry
from soe_jax.render import choice as render_choice
from soe_jax.runtime import cli, provenance
from soe_jax.serve import client as client_lib

USAGE = "python -m soe_jax bench SUB [flags]"


@dataclasses.dataclass(frozen=True)
class Benchmark:
  what: str  # one line, for the list of benchmarks
  doc: str  # what `SUB --help` prints above the flags: what it measures, then its usage line
  define: Callable[[cli.Flags], None]  # its flags
  run: Callable[[cli.Flags, list[str]], dict]  # (its parsed flags, its command line) -> the JSON line
  config: bool = False  # needs --config


def _ints(values: list[str], name: str) -> tuple[int, ...]:
  try:
    return tuple(int(v) for v in values)
  except ValueError:
    raise cli.UsageError(f"--{name} takes integers separated by commas; got {','.join(values)}") from None


# -- env ---------------------------------------------------------------------------------------------
def _env_flags(f: cli.Flags) -> None:
  f.enum("task", "lift", env_registry.env_names(), "Task name.")
  f.integer("num_envs", 64, "Batch of environments.", lower_bound=1)
  f.enum("backend", "auto", ["auto", *backends.BACKENDS.names()], "Physics backend.")
  f.enum("mjx_impl", "auto", ["auto", *backends.MJX_IMPLS], "MJX's implementation.")
  f.string("mjx_settings", "", "MJX's solver options ('' the task's, engine, or name=value,...).")
  f.boolean("unbatched", False, "One environment stepped without vmap (with --num_envs=1).")
  f.enum("obs_mode", "low_dim", list(observations.OBS_MODES), "Observations (image: both cameras drawn every step).")
  f.enum("renderer", "auto", ["auto", *render_choice.RENDERERS], "What draws the cameras (env.renderer).")
  f.integer("steps", None, "Control steps per compiled call (default 20 mujoco, 2 mjx).", lower_bound=1)
  f.integer("repeats", 3, "Timed calls.", lower_bound=1)
  f.string("out", None, "Also write the result record (for results/) here.")


def _env(f: cli.Flags, argv: list[str]) -> dict:
  if f.unbatched and f.num_envs != 1:
    raise cli.UsageError(f"--unbatched runs one environment: add --num_envs=1 (got --num_envs={f.num_envs})")
  source = provenance.header(argv)  # the code as it was when the measurement started
  result = env.run(f.task, f.num_envs, f.backend, f.steps, f.repeats, f.unbatched, f.mjx_impl, f.mjx_settings,
                   f.obs_mode, f.renderer)  # fmt: skip
  if f.out:
    records.write_record(dict(source, throughput=result), f.out, "env")
  return result


# -- mjx ---------------------------------------------------------------------------------------------
def _mjx_flags(f: cli.Flags) -> None:
  f.enum("task", "lift", expert_registry.expert_names(), "Task name (one with a scripted demonstrator).")
  f.enum("mjx_impl", "auto", ["auto", *backends.MJX_IMPLS], "MJX's implementation.")
  f.integer("num_envs", 64, "Demonstrations (start states) run on MJX.", lower_bound=1)
  f.string("mjx_settings", "", "MJX's solver options ('' the task's, engine, or name=value,...).")
  f.boolean("progress", True, "Progress bars.")
  f.string("out", None, "Also write the result record (for results/) here.")


def _mjx(f: cli.Flags, argv: list[str]) -> dict:
  result = mjx.run(f.task, f.mjx_impl, f.num_envs, f.mjx_settings, progress=f.progress, argv=argv)
  if f.out:
    records.write_record(result, f.out, "mjx")
  return result["mjx"]


# -- fit ---------------------------------------------------------------------------------------------
def _fit_flags(f: cli.Flags) -> None:
  f.config_flag()
  f.enum("bypass", "off", ["on", "off"], "Train the VIB bypass too.")
  f.enum("ema", "off", ["on", "off"], "Keep the EMA of parameters.")
  f.integer("steps", 10, "SGD steps per timed chunk.", lower_bound=1)
  f.integer("repeats", 2, "Timed chunks.", lower_bound=1)
  f.string("out", None, "Also write the result record (for results/) here, with the config.")


def _fit(f: cli.Flags, argv: list[str]) -> dict:
  source = provenance.header(argv)
  result = policy.fit(f.config, f.bypass == "on", f.ema == "on", f.steps, f.repeats)
  if f.out:
    records.write_record(dict(source, config=rundir.plain(f.config), fit_step=result), f.out, "fit_step")
  return result


# -- encoder -----------------------------------------------------------------------------------------
def _encoder_flags(f: cli.Flags) -> None:
  f.integer("batch", 64, "Batch size.", lower_bound=1)
  f.list("widths", ["64", "128", "256", "512"], "The ResNet-18 trunk's stem and stage channels.")
  f.integer("frames", 2, "Observation frames per sample.", lower_bound=1)
  f.integer("image_size", 84, "The cameras' image height and width.", lower_bound=8)
  f.integer("crop", 76, "The random crop's height and width.", lower_bound=4)
  f.boolean("shared", False, "One trunk for both cameras instead of one each.")
  f.integer("steps", 3, "SGD steps per timed chunk.", lower_bound=1)
  f.integer("repeats", 2, "Timed chunks.", lower_bound=1)
  f.string("out", None, "Also write the result record (for results/) here.")


def _encoder(f: cli.Flags, argv: list[str]) -> dict:
  widths = _ints(f.widths, "widths")
  source = provenance.header(argv)
  if f.crop > f.image_size:
    raise cli.UsageError(f"--crop={f.crop} is larger than --image_size={f.image_size}")
  result = encoder.run(f.batch, f.frames, widths, f.image_size, f.crop, f.steps, f.repeats, f.shared)
  if f.out:
    records.write_record(dict(source, encoder=result), f.out, "encoder")
  return result


# -- sample ------------------------------------------------------------------------------------------
def _sample_flags(f: cli.Flags) -> None:
  f.config_flag()
  f.integer("batch", 1, "Observations per chunk.", lower_bound=1)
  f.integer("steps", 10, "Denoising steps.", lower_bound=1)
  f.integer("repeats", 20, "Timed chunks.", lower_bound=1)


def _sample(f: cli.Flags, argv: list[str]) -> dict:
  return policy.sample(f.config, f.batch, f.steps, f.repeats)


# -- rollout -----------------------------------------------------------------------------------------
def _rollout_flags(f: cli.Flags) -> None:
  f.config_flag()
  f.string(
    "strategy", "", "Exploration strategy (dp, sime, soe, soe_steer, expert; default the config's, with its settings)."
  )
  f.integer("num_envs", 64, "Batch of environments.", lower_bound=1)
  f.integer("steps", 2, "Decisions per timed call.", lower_bound=1)
  f.integer("repeats", 3, "Timed calls.", lower_bound=1)


def _rollout(f: cli.Flags, argv: list[str]) -> dict:
  return rollout.run(f.config, f.strategy, f.num_envs, f.steps, f.repeats)


# -- torch -------------------------------------------------------------------------------------------
def _torch_flags(f: cli.Flags) -> None:
  f.list("down_dims", ["256", "512", "1024"], "UNet widths.")
  f.integer("step_embed_dim", 256, "Diffusion-step embedding size.", lower_bound=2)
  f.integer("batch", 256, "Fit batch size.", lower_bound=1)
  f.integer("threads", 2, "torch threads.", lower_bound=1)
  f.integer("steps", 5, "Timed fit steps.", lower_bound=1)


def _torch(f: cli.Flags, argv: list[str]) -> dict:
  dims = _ints(f.down_dims, "down_dims")
  return torch_reference.run(dims, f.step_embed_dim, f.batch, f.threads, f.steps)


# -- serve -------------------------------------------------------------------------------------------
def _serve_flags(f: cli.Flags) -> None:
  f.config_flag()
  f.integer("requests", 200, "Timed requests.", lower_bound=1)
  f.integer("warmup", 20, "Requests before the timed ones.", lower_bound=0)
  f.string(
    "camera_size", None, "HEIGHT,WIDTH of the images sent (e.g. 216,288; the server resizes them): the policy's own."
  )
  f.string("out", None, "Also write the result as a record (for results/) here.")


def _serve(f: cli.Flags, argv: list[str]) -> dict:
  camera_size = None
  if f.camera_size:
    try:
      camera_size = tuple(int(x) for x in f.camera_size.split(","))
    except ValueError:
      camera_size = ()
    if len(camera_size) != 2 or min(camera_size) < 1:
      raise cli.UsageError(f"--camera_size={f.camera_size}: expected HEIGHT,WIDTH, e.g. 216,288")
  source = provenance.header(argv)  # the code as it was when the measurement started
  result = serve_bench.serve(f.config, f.requests, f.warmup, camera_size)
  if f.out:
    records.write_record(dict(source, serve=result), f.out, "serve")
  return result


# -- realtime ----------------------------------------------------------------------------------------
def _realtime_flags(f: cli.Flags) -> None:
  f.string("checkpoint", None, "A fitted low-dim checkpoint of a simulated task (a run's round0/<name>/ckpt).")
  f.list("rates", ["10", "30"], "The robot's control rates, Hz.")
  f.float("delay_ms", 50.0, "Delay injected each way between the robot and the server, ms.", lower_bound=0.0)
  f.integer("states", 50, "Paired start states, the same for every rate and loop.", lower_bound=1)
  f.integer("seed", 0, "The start states' seed.")
  f.list("loops", list(realtime_bench.LOOPS), "The loops compared: blocking, realtime.")
  f.integer("threshold", -1, "Real-time chunks: ask for the next chunk at this many actions left (-1: half).",
            lower_bound=-1)  # fmt: skip
  f.enum("aggregate", "latest", list(client_lib.AGGREGATES), "Real-time chunks: how overlapping chunks combine.")
  f.string("mode", "base", "The server's mode: base, soe or sime.")
  f.boolean("progress", True, "A line per episode.")
  f.string("out", None, "Also write the result as a record (for results/) here.")


def _realtime(f: cli.Flags, argv: list[str]) -> dict:
  if not f.checkpoint:
    raise cli.UsageError("--checkpoint is required: a fitted low-dim checkpoint of a simulated task")
  try:
    rates = tuple(float(r) for r in f.rates)
  except ValueError:
    raise cli.UsageError(f"--rates takes numbers separated by commas; got {','.join(f.rates)}") from None
  if bad := [r for r in rates if not r > 0]:
    raise cli.UsageError(f"--rates: a rate is a number of Hz > 0, got {bad[0]:g}")
  if bad := [x for x in f.loops if x not in realtime_bench.LOOPS]:
    raise cli.UsageError(f"--loops: unknown loop {bad[0]!r}; known: {', '.join(realtime_bench.LOOPS)}")
  settings = client_lib.RealTime(None if f.threshold < 0 else f.threshold, f.aggregate)
  source = provenance.header(argv)  # the code as it was when the measurement started
  say = (lambda line: print(line, file=sys.stderr, flush=True)) if f.progress else None
  try:
    result = realtime_bench.run(f.checkpoint, rates, f.delay_ms, f.states, f.seed, tuple(f.loops), settings, f.mode,
                                say)  # fmt: skip
  except (FileNotFoundError, ValueError) as e:
    raise cli.UsageError(str(e)) from None
  if f.out:
    records.write_record(dict(source, realtime=result), f.out, "realtime")
  return result


BENCHMARKS = {
  "env": Benchmark(
    "environment throughput: control steps per second summed over a batch",
    """Environment throughput: control steps per second summed over a batch, compile excluded (with
--obs_mode=image, both cameras drawn every step).

  python -m soe_jax bench env --task=square --num_envs=256 [--backend=mujoco|mjx --mjx_impl=jax|warp]
      [--num_envs=1 --unbatched] [--obs_mode=image --renderer=auto|gl|warp] [--out=results/render/<name>.json]""",
    _env_flags,
    _env,
  ),
  "mjx": Benchmark(
    "the MJX backend against the C engine: demonstrator success, paths, sizes, times",
    """The MJX backend against the C engine on one task: the demonstrator's success on MJX, the paths of
both backends, the contacts and constraints the scene uses, compile and run times.

  python -m soe_jax bench mjx --task=lift --mjx_impl=warp --num_envs=200 [--out=results/mjx/lift-warp.json]""",
    _mjx_flags,
    _mjx,
  ),
  "fit": Benchmark(
    "the policy's fit step on random data: milliseconds per SGD step",
    """The policy's fit step on random data in memory: whole compiled chunks of SGD steps timed, the mean
per step reported.

  python -m soe_jax bench fit --config=configs/square.py [--bypass=on|off] [--ema=on|off] [--steps=10] [--out=FILE]""",
    _fit_flags,
    _fit,
    config=True,
  ),
  "encoder": Benchmark(
    "the image encoder's share of an image policy's fit step",
    """The image encoder's share of an image policy's fit step (both cameras' ResNet-18s), on random
images in memory, with its FLOPs and bytes against this machine's floors.

  python -m soe_jax bench encoder [--batch=64 --widths=64,128,256,512 --frames=2 --image_size=84 --crop=76 --shared]
      [--out=results/encoder/<name>.json]""",
    _encoder_flags,
    _encoder,
  ),
  "sample": Benchmark(
    "one action chunk's sampling: milliseconds per chunk",
    """One action chunk's sampling (the configured sampler with --steps denoising steps), compile
excluded.

  python -m soe_jax bench sample --config=configs/square.py --batch=1 --steps=10""",
    _sample_flags,
    _sample,
    config=True,
  ),
  "rollout": Benchmark(
    "rollout throughput with the policy and an exploration strategy in the loop",
    """Rollout throughput with the policy in the loop: a batch of environments, a fresh policy of the
config's size and one exploration strategy (the config's settings when it names the same one).

  python -m soe_jax bench rollout --config=configs/lift.py:cpu --strategy=soe --num_envs=100""",
    _rollout_flags,
    _rollout,
    config=True,
  ),
  "torch": Benchmark(
    "PyTorch reference timings of the UNet's fit step and sampling (needs torch)",
    """PyTorch reference timings of Diffusion Policy's UNet (fit step, one DDIM chunk) on this machine's
CPUs; needs `pip install torch` (not a dependency).

  python -m soe_jax bench torch --down_dims=256,512,1024 --step_embed_dim=256 --batch=256""",
    _torch_flags,
    _torch,
  ),
  "serve": Benchmark(
    "the policy server's latency per chunk over loopback against in-process",
    """The policy server's latency per chunk (`soe_jax/bench/serve.py`): p50 / p95 over --requests
requests after --warmup, over loopback and in-process, compile apart; --camera_size sends each camera at a
robot's size, which the server resizes to the policy's.

  python -m soe_jax bench serve --config=configs/lift.py:cpu [--camera_size=216,288] [--out=results/serve/<name>.json]""",
    _serve_flags,
    _serve,
    config=True,
  ),
  "realtime": Benchmark(
    "real-time chunks against the blocking loop, the simulator as a robot at its own rate",
    """Real-time chunks against the blocking loop (`soe_jax/bench/realtime.py`): the simulator advances one
control step per wall-clock tick at each --rates whether or not an action is ready (holding the last
command), --delay_ms injected each way; idle time per second, dropped actions, success on --states
paired start states, the machine's load.

  python -m soe_jax bench realtime --checkpoint=RUN/round0/<name>/ckpt [--rates=10,30 --delay_ms=50 --states=50]
      [--loops=blocking,realtime --threshold=-1 --aggregate=latest|ensemble] [--out=results/realtime/<name>.json]""",
    _realtime_flags,
    _realtime,
  ),
}


def flags(name: str) -> cli.Flags:
  """A fresh set of benchmark `name`'s flags."""
  f = cli.Flags()
  BENCHMARKS[name].define(f)
  return f


FLAGS = {name: flags(name) for name in BENCHMARKS}


def help_text() -> str:
  """The module's docstring, then each benchmark's name and what it measures."""
  width = max(map(len, BENCHMARKS))
  lines = [f"  {name:<{width}}  {b.what}" for name, b in BENCHMARKS.items()]
  return __doc__.strip() + "\n\nbenchmarks:\n" + "\n".join(lines) + "\n"


def _run(name: str, argv: list[str], rest: list[str]) -> None:
  cli.positional(rest, "0", f"python -m soe_jax bench {name} [flags]")
  print(json.dumps(BENCHMARKS[name].run(FLAGS[name], argv)))


def main(argv: list[str] | None = None) -> None:
  argv = list(sys.argv if argv is None else argv)
  name = argv[1] if len(argv) > 1 else None
  if name in ("-h", "--help", "-help", "--helpshort", "--helpfull", "help"):
    print(help_text(), end="")
    sys.exit(0)
  if name not in BENCHMARKS:
    what = f"unknown benchmark {name!r}" if name else "missing the benchmark"
    cli.fail(f"{what}; usage: {USAGE} with SUB one of {', '.join(BENCHMARKS)} (--help lists them)")
  sub = [f"{argv[0]} {name}", *argv[2:]]  # "python -m soe_jax bench env", its flags
  required = ("config",) if BENCHMARKS[name].config else ()
  cli.run(lambda rest: _run(name, sub, rest), FLAGS[name], BENCHMARKS[name].doc, sub, required=required, compiles=True)
