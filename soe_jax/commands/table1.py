"""The paper's Table I from a robot's labelled episodes: per mode, success with its interval, Pass@k and
the rollouts to the first success over the attempt groups, and jerk; and the success before and after
a re-fit (`analysis/labelled.py`). With `--method`, one row per method sharing one evaluation before.

  python -m soe_jax table1 RECORDED [--before=EVAL0 --after=EVAL1] [--k=5] [--spec=WORKDIR] [--out=FILE.json]
  python -m soe_jax table1 --before=EVAL0 --method dp=EXPLORE_DP:EVAL_DP --method sime=... --method soe=...

RECORDED, EVAL0 and EVAL1 are LeRobotDatasets with `next.success` (what `serve --record` writes: the
exploration episodes, and evaluations of the policy before and after `refit`, each in the base mode).
Pass@k needs a `start_state` per episode (the attempt group a person gave when labelling); states with
fewer than k tries are left out of it and counted. Jerk uses each arm's commanded position, laid out as
the policy's spec says (--spec: a robot workdir or checkpoint with spec.json; default one arm, its
first three numbers), at the dataset's frame rate.

`--method NAME=EXPLORE:AFTER` (repeated, in the order to show) names a method's exploration recording
(every episode of it, whatever its mode) and the evaluation of its re-fitted policy; either may be left
empty (`soe=EXPLORE:`). Every method's after is set against the one `--before`, and each pair of
methods against each other by the start states they share (the sign test over the states' success
rates), after the re-fit and in exploration.
"""

from __future__ import annotations

from soe_jax.runtime import atomic, cli, provenance
from soe_jax.runtime.errors import UserError

USAGE = (
  "python -m soe_jax table1 RECORDED [--before=EVAL0 --after=EVAL1] [--k=5] [--spec=DIR] [--out=FILE], or "
  "python -m soe_jax table1 [--before=EVAL0] --method NAME=EXPLORE:AFTER [--method ...] [--k=5] [--spec=DIR] "
  "[--out=FILE]"
)

FLAGS = cli.Flags()
FLAGS.string("before", None, "Labelled evaluation episodes of the policy before the re-fit.")
FLAGS.string("after", None, "Labelled evaluation episodes of the re-fitted policy (with --before).")
FLAGS.multi_string("method", [], "NAME=EXPLORE:AFTER: a method's exploration recording and the evaluation after its "
                   "re-fit (either may be empty)")  # fmt: skip
FLAGS.integer("k", 5, "Tries per start state for Pass@k and the rollouts.", lower_bound=1)
FLAGS.string("spec", None, "A directory with the policy's spec.json (the action layout for jerk).")
FLAGS.string("out", None, "Also write the table here (JSON, with the command and commit).")


def parse_methods(values: list[str]) -> dict[str, tuple[str | None, str | None]]:
  """['dp=EXPLORE:AFTER', ...] -> {"dp": (EXPLORE or None, AFTER or None)}, in order."""
  out = {}
  for value in values:
    name, eq, paths = value.partition("=")
    parts = paths.split(":")
    if not eq or not name or len(parts) != 2 or not any(parts):
      raise UserError(f"--method {value}: NAME=EXPLORE:AFTER expected (one of the two may be empty)")
    if name in out:
      raise UserError(f"--method {name} is given twice")
    out[name] = (parts[0] or None, parts[1] or None)
  return out


def _table1(argv: list[str]) -> None:
  args = cli.positional(argv, "0+", USAGE)
  if len(args) > 1:
    raise UserError(f"one recorded dataset at a time; usage: {USAGE}")
  recorded = args[0] if args else None
  methods = parse_methods(FLAGS.method)
  if methods and (recorded is not None or FLAGS.after is not None):
    raise UserError("with --method, each method names its own recording and evaluation after (NAME=EXPLORE:AFTER); "
                    "give no RECORDED or --after")  # fmt: skip
  if not methods and (FLAGS.before is None) != (FLAGS.after is None):
    raise UserError("--before and --after go together (two evaluations of the policy around a re-fit)")
  if recorded is None and FLAGS.before is None and not methods:
    raise UserError(f"nothing to tabulate; usage: {USAGE}")
  from soe_jax.analysis import labelled
  from soe_jax.data import lerobot
  from soe_jax.data import spec as spec_lib

  positions = None
  if FLAGS.spec:
    spec = spec_lib.load(FLAGS.spec)
    if spec is None:
      raise UserError(f"--spec: {FLAGS.spec} has no {spec_lib.SPEC_FILE}")
    positions = spec.position_indices(robot=True)  # (the recordings hold the robot's action)
  try:
    read = lambda root: None if root is None else labelled.read(root, positions)
    if methods:
      rows = {name: (read(explore), read(after)) for name, (explore, after) in methods.items()}
      table = labelled.methods_table(rows, FLAGS.k, read(FLAGS.before))
      text = labelled.methods_markdown(table)
    else:
      table = labelled.table(read(recorded), FLAGS.k, read(FLAGS.before), read(FLAGS.after))
      text = labelled.markdown(table)
  except lerobot.DatasetError as e:
    raise UserError(str(e)) from None
  print(text)
  if FLAGS.out:
    atomic.write_json(FLAGS.out, dict(provenance.header(), **table))
    print(f"-> {FLAGS.out}")


def main(argv: list[str] | None = None) -> None:
  cli.run(_table1, FLAGS, __doc__, argv)
