# Sourced by the science scripts whose committed arms were measured before the `cpu` preset adopted
# what they found:
#   measured_as SPEC ARM COMMIT FIELD=VALUE...
# returns when SPEC's ARM arm has every FIELD (a dotted config path) at VALUE (a Python literal, else a
# string), the setting the committed results were measured under; otherwise it names the fields that
# differ and the commit to run at, and exits 2 before anything has run.
measured_as() {
  local spec=$1 arm=$2 commit=$3 differs
  shift 3
  differs=$(python -c 'import ast, sys
from soe_jax.runtime import configfile
spec, arm, *pairs = sys.argv[1:]
node = configfile.load(spec, arm)
differs = []
for pair in pairs:
  field, want = pair.split("=", 1)
  try:
    want = ast.literal_eval(want)
  except (ValueError, SyntaxError):
    pass
  got = node
  for key in field.split("."):
    got = got[key]
  if got != want:
    differs.append(f"{field} is {got!r}, not {want!r}")
print("; ".join(differs))' "$spec" "$arm" "$@") || exit 2
  [[ -z $differs ]] && return
  echo "$spec: its $arm arm differs from the setting this script's committed results were measured" \
    "under ($differs), so its arms would not be those results'" \
    "arms; run it at commit $commit (git worktree add --detach DIR $commit) or with a CONFIG without the" \
    "change" >&2
  exit 2
}
