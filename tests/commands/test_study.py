"""A new study is one file: registered by name, it is in `study`'s list, its settings are its flags,
its record is written with its kind and `results` tables it; the studies' own command names run them
with the same flags."""

import json

import pytest

from soe_jax import __main__ as entry
from soe_jax.analysis import results
from soe_jax.analysis.studies import registry
from soe_jax.commands import study as command


@pytest.fixture
def toy(monkeypatch):
  """The toy study (`toy_study.py`) registered as "toy" while the test runs."""
  monkeypatch.setitem(registry.STUDIES._factories, "toy", "tests.commands.toy_study:Toy")
  yield
  command.FLAGS.pop("toy", None)


def _main(capsys, *args) -> tuple[int, str, str]:
  """`python -m soe_jax ARGS` in this process -> (exit status, stdout, stderr)."""
  try:
    entry.main(["soe_jax", *args])
    code = 0
  except SystemExit as e:
    code = e.code
  out = capsys.readouterr()
  return code, out.out, out.err


def test_a_registered_study_is_listed_with_its_flags(toy, capsys):
  code, listed, _ = _main(capsys, "study")
  assert code == 0 and "  toy " in listed and "The sizes of the files given, as a record" in listed
  assert [line.split()[0] for line in listed.split("studies:\n")[1].splitlines()] == registry.study_names()
  code, helped, _ = _main(capsys, "study", "toy", "--help")
  assert code == 0 and helped.startswith("The sizes of the files given")
  for flag in ("--scale: What each size is multiplied by. (default: '1.0')", "--unit: <bytes|kilobytes>",
               "--skip: Positions of files left out.", "--label:", "--out: Also write the record"):  # fmt: skip
    assert flag in helped, flag


def test_a_registered_study_runs_writes_its_record_and_results_tables_it(toy, capsys, tmp_path):
  for name, size in (("a", 1500), ("b", 500), ("c", 7)):
    (tmp_path / name).write_bytes(b"x" * size)
  files = [str(tmp_path / n) for n in ("a", "b", "c")]
  out = tmp_path / "toy" / "01_first.json"
  code, printed, err = _main(capsys, "study", "toy", *files, "--scale=2", "--unit=kilobytes", "--skip=2",
                             "--label=two files", f"--out={out}")  # fmt: skip
  assert code == 0, err
  record = json.loads(out.read_text())
  assert record == dict(kind="toy_sizes", command="toy", label="two files", unit="kilobytes", sizes=[3.0, 1.0])
  assert printed.splitlines()[2] == "| toy | two files | 4 kilobytes |" and printed.endswith(f"-> {out}\n")
  assert results.table(str(tmp_path / "toy")).splitlines()[2] == "| 01_first | two files | 4 kilobytes |"


@pytest.mark.parametrize(
  "args, error",
  [
    (["--unit=miles"], "flag --unit=miles: value should be one of <bytes|kilobytes>"),
    (["--scale=-1"], "flag --scale=-1: -1.0 is not a non-negative number"),
    (["--skip=x"], "--skip takes ints separated by commas; got x"),
    (["--sizes=1"], "Unknown command line flag 'sizes'"),
    ([], "missing arguments; usage: python -m soe_jax study toy FILE [FILE ...] [flags]"),
  ],
)
def test_a_registered_studys_flags_refuse_what_its_settings_do_not_take(toy, capsys, tmp_path, args, error):
  (tmp_path / "a").write_bytes(b"x")
  files = [str(tmp_path / "a")] if args else []
  code, _, err = _main(capsys, "study", "toy", *files, *args)
  assert code == 2 and err.startswith("error: ") and error in err, err


def test_an_unknown_study_is_one_error_line_naming_the_studies(capsys):
  code, _, err = _main(capsys, "study", "nonsense")
  assert code == 2 and err.startswith("error: unknown study 'nonsense'; known studies: action_range, calibrate")


def test_every_studys_own_command_name_is_a_study_with_the_same_flags(capsys):
  """`python -m soe_jax NAME` (the names launch scripts and committed records use) is `study NAME`."""
  assert set(entry.STUDY_COMMANDS) <= set(registry.study_names())
  assert not set(entry.STUDY_COMMANDS) & set(entry.COMMANDS)
  for name in entry.STUDY_COMMANDS:
    code, own, _ = _main(capsys, name, "--help")
    assert code == 0 and f"python -m soe_jax study {name}" in own
    assert (0, own, "") == _main(capsys, "study", name, "--help")
  listing = _main(capsys, "--help")[1]
  assert listing.index("bench ") < listing.index(", ".join(entry.STUDY_COMMANDS))  # after the commands
