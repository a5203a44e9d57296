"""Every attribute the package, its configs and its launch scripts read off a soe_jax module exists
(`checkpoint.policy_from_config` after a move, say): such a name fails only when its line runs, and
some lines (the benchmarks) run in no default test."""

import ast
import importlib
import importlib.util
import pathlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
PLACES = ("soe_jax", "configs", "launch")


def _module(name: str) -> bool:
  try:
    return importlib.util.find_spec(name) is not None
  except ModuleNotFoundError:
    return False


def module_names(tree: ast.AST) -> dict[str, str]:
  """Local name -> the soe_jax module it is bound to (`from soe_jax.x import y [as z]` where y is a
  module, `import soe_jax.x as z`)."""
  names = {}
  for node in ast.walk(tree):
    if isinstance(node, ast.Import):
      names.update({a.asname: a.name for a in node.names if a.name.startswith("soe_jax.") and a.asname})
    elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "soe_jax":
      for a in node.names:
        if _module(full := f"{node.module}.{a.name}"):
          names[a.asname or a.name] = full
  return names


def missing(source: str, where: str) -> tuple[int, list[str]]:
  """(attributes `source` reads off soe_jax modules, those the module lacks as 'where:line: module.name')."""
  tree = ast.parse(source)
  names, read, absent = module_names(tree), 0, []
  for node in ast.walk(tree):
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in names:
      read += 1
      if not hasattr(importlib.import_module(names[node.value.id]), node.attr):
        absent.append(f"{where}:{node.lineno}: {names[node.value.id]}.{node.attr}")
  return read, absent


def test_the_checker_finds_a_name_a_module_lacks():
  source = "from soe_jax.train import checkpoint\n\ncheckpoint.policy_from_spec\ncheckpoint.policy_from_config\n"
  assert missing(source, "probe.py") == (2, ["probe.py:4: soe_jax.train.checkpoint.policy_from_config"])


def test_every_attribute_read_off_a_soe_jax_module_exists():
  read, absent = 0, []
  for place in PLACES:
    for path in sorted((ROOT / place).rglob("*.py")):
      n, a = missing(path.read_text(), str(path.relative_to(ROOT)))
      read, absent = read + n, absent + a
  assert read > 900 and absent == []
