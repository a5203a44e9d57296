#!/usr/bin/env bash
# The experiments that decide each suspect of "why own successes hurt" (README), on Lift with the
# workspace box, one training seed per call so a session can finish it whole:
#   bash launch/why_own_successes.sh SEED [WORKDIR] [PART]
# PART a (about 75 min here): one campaign invocation with the shared control and the arms of suspects
#   2 and 3 (alpha 0, the re-fit's demonstration share, aligned windows), exported to
#   results/why-own-successes/lift/seed<k>/; then the relabelled arms (labels against states) from its dp
#   and soe runs, exported beside; then the fidelity study on its dp, soe and soe alpha=0 runs.
# PART b (about 80 min): the KL weight's dose-response, each beta with a round 0 of its own, with its own
#   control and soe, to results/why-own-successes-beta/; then the fidelity study on soe and beta = 0, and
#   the latent study (effective dimensions) of each beta's round 0 to results/why-own-successes-beta-latent/.
# PART c (about 35 min): the setting that brought SOE level with the control on 3 seeds (aligned windows)
#   re-evaluated on evaluation start states no experiment had used (eval.seed 55555): control, dp, soe
#   and both with aligned windows, to results/why-own-successes-eval55555/.
# PART square (about 60-90 min): the settings that moved SOE most on Lift repeated on Square, where the
#   harm is largest: part d's arms (control, soe, soe at BETA, soe with aligned windows, soe with both) on
#   configs/square.py:cpu (SQUARE_CONFIG), to results/why-own-successes-square/ (work directory WORKDIR-square).
# PART d (about 45 min): the KL weight that README item 6 picks (BETA, required) re-evaluated on evaluation
#   start states no experiment had used (eval.seed 44444): control, soe, soe at BETA, soe with aligned
#   windows and soe with both, to results/why-own-successes-eval44444/ (work directory WORKDIR-eval44444).
# PART all: a and b, one after the other (too long for one session on this CPU).
# Every part measures its arms as the `cpu` preset defined them before it adopted what they found (the
# KL weight 1e-5 and aligned windows; f21cbfe is the last commit before): with a config whose soe arm
# has either, its `soe` would be another arm than the committed results' `soe`, so the script refuses
# and names that commit.
# Work directories under WORKDIR, default $RUNS/why (`launch/runs.sh`: RUNS, else the main checkout's
# runs/, never inside a pinned worktree; part b uses WORKDIR-beta); re-running resumes. CONFIG (default
# configs/lift.py:cpu) and RESULTS (default results) may be set in the environment, e.g.
# CONFIG=configs/lift.py:smoke RESULTS=/tmp/why for a quick check of the whole path.
set -euo pipefail
source "$(dirname "$0")/measured_as.sh"
source "$(dirname "$0")/runs.sh"
seed=${1:?the training seed}
runs=${2:-$(runs_root)/why}
part=${3:-all}
case $part in a|b|c|d|all|square) ;; *) echo "unknown part '$part'; known: a, b, c, d, square, all" >&2; exit 2;; esac
[[ ($part != d && $part != square) || -n ${BETA:-} ]] || {
  echo "part $part needs BETA, the KL weight README item 6 picks" >&2; exit 2; }
config=${CONFIG:-configs/lift.py:cpu}
out=${RESULTS:-results}
before_adoption=f21cbfe
spec=$config
[[ $part == square ]] && spec=${SQUARE_CONFIG:-configs/square.py:cpu}
measured_as "$spec" soe "$before_adoption" policy.bypass.beta=1e-3 rounds.aligned_windows=False
# Parts d and square: the picked KL weight and aligned windows, each alone and together, beside soe.
beta_arms="control,soe,soe+beta=${BETA:-},soe+aligned=true,soe+beta=${BETA:-}+aligned=true"
if [[ $part == a || $part == all ]]; then
  results=$out/why-own-successes
  python -m soe_jax campaign --config="$config" --config.seed="$seed" \
    --methods=control,dp,soe,soe+alpha=0,dp+demo_fraction=0.5,soe+demo_fraction=0.5,dp+aligned=true,soe+aligned=true \
    --workdir="$runs" --results="$results" --progress=false
  base="$runs/lift/seed$seed"
  for args in "dp --labels=explore --alpha=0" "dp --labels=explore --alpha=2" "soe --labels=base" "dp --labels=base --seed=1"; do
    set -- $args
    python -m soe_jax relabel "$base/$1" "${@:2}" --results="$results" --progress=false
  done
  python -m soe_jax fidelity "$base/dp" "$base/soe" "$base/soe-alpha0" --out="$out/fidelity/lift_seed$seed.json"
fi
if [[ $part == b || $part == all ]]; then
  python -m soe_jax campaign --config="$config" --config.seed="$seed" \
    --methods=control,soe,soe+beta=0.0001,soe+beta=1e-05,soe+beta=0 \
    --workdir="$runs-beta" --results="$out/why-own-successes-beta" --progress=false
  base="$runs-beta/lift/seed$seed"
  python -m soe_jax fidelity "$base/soe" "$base/soe-beta0" --out="$out/fidelity/lift_beta_seed$seed.json"
  for beta in 0.001 0.0001 1e-05 0; do  # the effective dimensions of each beta's round 0 (its own round 0)
    python -m soe_jax latent --config="$config" --config.seed="$seed" --config.policy.bypass.beta="$beta" \
      --config.rounds.round0_dir="$base/round0" --workdir="$runs-beta-latent/lift/seed$seed/beta$beta" \
      --out="$out/why-own-successes-beta-latent/lift_beta${beta}_seed$seed.json" --progress=false
  done
fi
if [[ $part == c ]]; then
  python -m soe_jax campaign --config="$config" --config.seed="$seed" --config.eval.seed=55555 \
    --methods=control,dp,soe,dp+aligned=true,soe+aligned=true \
    --workdir="$runs-eval55555" --results="$out/why-own-successes-eval55555" --progress=false
fi
if [[ $part == d ]]; then
  python -m soe_jax campaign --config="$config" --config.seed="$seed" --config.eval.seed=44444 \
    --methods="$beta_arms" --workdir="$runs-eval44444" --results="$out/why-own-successes-eval44444" --progress=false
fi
if [[ $part == square ]]; then
  python -m soe_jax campaign --config="$spec" --config.seed="$seed" \
    --methods="$beta_arms" --workdir="$runs-square" --results="$out/why-own-successes-square" --progress=false
fi
