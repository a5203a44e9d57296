# Sourced by the launch scripts: the folder their work directories go under by default,
#   runs_root   ->  $RUNS if set, else runs/ in this repository's main checkout
# The main checkout's even when the script runs from a linked worktree (one pinned to the commit a part's
# results were measured at, `git worktree add --detach DIR COMMIT`): such a worktree is removed after,
# and runs inside it would go with it. Outside a git checkout: runs/ beside launch/.
runs_root() {
  if [[ -n ${RUNS:-} ]]; then
    echo "$RUNS"
    return
  fi
  local here common
  here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
  if common=$(git -C "$here" rev-parse --path-format=absolute --git-common-dir 2>/dev/null); then
    echo "$(dirname "$common")/runs"  # (the common git directory is the main checkout's .git)
  else
    echo "$here/runs"
  fi
}
