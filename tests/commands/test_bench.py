"""`python -m soe_jax bench SUB`: each benchmark's own flags and help, mistakes as one line, and the
record of `--out` naming the command as it was typed (nothing here measures: the benchmark itself is
replaced)."""

import json

import numpy as np
import pytest

from soe_jax.commands import bench
from soe_jax.runtime import provenance


@pytest.fixture(autouse=True)
def fresh_flags():
  """Each test's command lines parsed from the defaults (a command's flags keep what the last parse set)."""
  for flags in bench.FLAGS.values():
    flags.unparse_flags()


def _exit(argv: list[str], capsys) -> tuple[int, str, str]:
  with pytest.raises(SystemExit) as exit:
    bench.main(["python -m soe_jax bench", *argv])
  out, err = capsys.readouterr()
  return exit.value.code, out, err


def test_help_lists_the_benchmarks_and_each_one_only_its_flags(capsys):
  """`bench --help` lists the benchmarks, and each benchmark's help only its own flags."""
  code, out, _ = _exit(["--help"], capsys)
  assert code == 0 and all(f"\n  {name} " in out for name in bench.BENCHMARKS)
  assert "converge" not in out and "latent" not in out
  code, out, _ = _exit(["env", "--help"], capsys)
  assert code == 0 and "python -m soe_jax bench env" in out
  assert "--unbatched:" in out and "--config" not in out and "--bypass" not in out and "--strategy" not in out
  code, out, _ = _exit(["fit", "--help"], capsys)
  assert code == 0 and "--steps: SGD steps per timed chunk. (default: '10')" in out and "--task" not in out
  code, out, _ = _exit(["sample", "--help"], capsys)
  assert (
    code == 0
    and "--steps: Denoising steps. (default: '10')" in out
    and "--batch: Observations per chunk. (default: '1')" in out
  )
  code, out, _ = _exit(["encoder", "--help"], capsys)
  assert code == 0 and "--batch: Batch size. (default: '64')" in out


@pytest.mark.parametrize(
  "argv, message",
  [
    ([], "missing the benchmark"),
    (["converge"], "unknown benchmark 'converge'"),
    (["env", "--config=configs/lift.py"], "Unknown command line flag 'config'"),
    (["fit"], "--config=configs/<task>.py[:PRESETS] is required"),
    (["env", "--unbatched"], "--unbatched runs one environment: add --num_envs=1"),
    (["env", "--task=stack"], "flag --task=stack: value should be one of"),
    (["encoder", "--widths=64,wide"], "--widths takes integers"),
    (["serve", "--config=configs/lift.py:smoke", "--camera_size=216"], "--camera_size=216: expected HEIGHT,WIDTH"),
    (["env", "extra"], "unexpected arguments: extra"),
  ],
)
def test_a_mistake_is_one_line_and_exit_status_2(argv, message, capsys):
  code, out, err = _exit(argv, capsys)
  assert code == 2 and out == "" and err.startswith("error: ") and message in err and err.count("\n") == 1, err


def test_bench_serve_sends_the_cameras_at_the_size_asked_and_tables_it(monkeypatch, capsys):
  """`--camera_size` reaches the benchmark, whose requests carry every camera at that size; the table
  says the images were sent at it."""
  from configs import lift as lift_config
  from soe_jax.analysis import records
  from soe_jax.bench import serve as serve_bench
  from soe_jax.experiment import task

  spec = task.spec(lift_config.get_config("smoke,image"))
  obs = serve_bench._observations(spec, 2, np.random.default_rng(0), (216, 288))
  assert spec.image_keys and all(
    o[k].shape == (216, 288, 3) and o[k].dtype == np.uint8 for o in obs for k in spec.image_keys
  )
  monkeypatch.setattr(serve_bench, "serve", lambda config, requests, warmup, camera_size: dict(camera_size=camera_size))
  bench.main(["python -m soe_jax bench", "serve", "--config=configs/lift.py:smoke,image", "--camera_size=216,288"])
  assert json.loads(capsys.readouterr().out.splitlines()[-1]) == dict(camera_size=[216, 288])
  ms = dict(p50=1.0, p95=2.0)
  s = dict(task="lift", obs_encoder="image", down_dims=[8], images=[[84, 84, 3]], sent=[[216, 288, 3]], requests=5,
           compile_s=1.0, in_process_ms=ms, round_trip_ms=ms, wire_overhead_ms=0.0, request_bytes=1)  # fmt: skip
  assert "images [[84, 84, 3]] sent as [[216, 288, 3]]" in records.serve_table([("r", dict(serve=s, machine="m"))])


def test_the_record_of_out_names_the_command_as_typed(tmp_path, monkeypatch, capsys):
  monkeypatch.setattr(bench.env, "run", lambda *args: dict(control_steps_per_s=1.0, args=list(args)))
  out = str(tmp_path / "env.json")
  bench.main(["python -m soe_jax bench", "env", "--task=square", "--num_envs=1", "--unbatched", f"--out={out}"])
  result = json.loads(capsys.readouterr().out.splitlines()[-1])
  assert result["args"][:2] == ["square", 1] and result["args"][3:6] == [None, 3, True]  # steps: the backend's
  with open(out) as f:
    record = json.load(f)
  assert record["command"] == f"python -m soe_jax bench env --task=square --num_envs=1 --unbatched --out={out}"
  assert record["throughput"] == result and record["commit"] and record["machine"]


def test_a_command_is_named_as_it_was_typed():
  assert provenance.command(["/src/soe_jax/__main__.py", "bench", "env", "--out=a b"]) == (
    "python -m soe_jax bench env '--out=a b'"
  )
  assert provenance.command(["python -m soe_jax bench mjx", "--task=can"]) == "python -m soe_jax bench mjx --task=can"
  assert provenance.command(["/src/soe_jax/main.py", "--config=x"]) == "python -m soe_jax.main --config=x"
  assert provenance.command(["launch/gpu_physics.py", "--budget=5"]) == "python launch/gpu_physics.py --budget=5"


@pytest.mark.slow
def test_bench_serve_times_the_server_against_in_process_and_tables_its_record(tmp_path, capsys):
  from soe_jax.analysis import results

  out = str(tmp_path / "serve" / "smoke.json")
  bench.main(["python -m soe_jax bench", "serve", "--config=configs/lift.py:smoke", "--requests=5", "--warmup=2",
              f"--out={out}"])  # fmt: skip
  result = json.loads(capsys.readouterr().out.splitlines()[-1])
  assert result["requests"] == 5 and result["round_trip_ms"]["p50"] > 0 and result["in_process_ms"]["p50"] > 0
  assert "| smoke | lift lowdim [16, 32, 64] | 5 |" in results.table(str(tmp_path / "serve"))
