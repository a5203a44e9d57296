#!/usr/bin/env bash
# The protocol issue's experiments on Lift, one training seed per call so a session can finish it whole
# (docs/protocol.md is the rule that reads them):
#   bash launch/protocol.sh PART SEED [WORKDIR]
# PART sime-count-N: round 0 and its control (a re-fit from scratch on the same data) under SIME's
#   protocol with N demonstrations, to results/protocol-count/sime-nN/: the demonstration count's
#   calibration and the control's reproducibility check.
# PART varied-count-N: round 0 and its control on N varied demonstrations under the present protocol,
#   to results/protocol-count/varied-nN/: the varied data's count calibration.
# PART picked-count-TASK-N (TASK lift, can or square): round 0 alone (no round, no control: the main
#   campaign's control is the reproducibility check at the count picked) under what docs/protocol.md
#   picked before its count (SIME's protocol on varied demonstrations, RESULTS.md "Applying the rule")
#   with N demonstrations, to results/protocol-count/picked-TASK-nN/: that count's calibration.
# PART sime-N: dp, sime, soe and the control under SIME's protocol with N demonstrations, one
#   invocation, to results/protocol-sime/nN/.
# PART style-N: dp, sime, soe and the control on scripted and on varied demonstrations (N of each,
#   the present protocol), one invocation, to results/demo-style-campaign/nN/; then the latent study
#   (effective dimensions) on each, to results/latent-style/.
# PART main-TASK (TASK lift, can or square): the main campaign on the protocol docs/protocol.md picked
#   (the `cpu` preset once it is applied): dp, sime, soe, soe_steer, the control and both expert_data
#   arms, one round, evaluated on start states neither science issue used (eval.seed 33333), one
#   invocation, to results/protocol-main/TASK/.
# PART main-TASK-1, main-TASK-2, main-TASK-3: the same arms in three invocations, each with its own
#   round 0 and control (control, dp, sime, soe | control, soe_steer | control, dp+expert_data,
#   soe+expert_data), for a seed that would not finish within one session, to
#   results/protocol-main/TASK-1/, TASK-2/ and TASK-3/ (Square's first part: 1 h 31 to 1 h 48 min a
#   seed on 2 cores of an AMD EPYC).
# PART rounds-lift: dp, sime, soe and the control on Lift over 3 rounds, eval.seed 33333, one
#   invocation, to results/protocol-rounds/lift/ (2 h 38 to 2 h 52 min a seed on 2 cores of an AMD EPYC).
# PART rounds-lift-1, rounds-lift-2: the same arms in two shorter invocations, each with its own round 0 and
#   control over 3 rounds (control, dp, soe | control, sime), to results/protocol-rounds/lift-1/ and
#   lift-2/.
# PART decompose-lift: which of the picked protocol's differences from the first protocol SOE's round
#   on Lift answers to, under the `cpu` preset (varied demonstrations, eval.seed 33333), one invocation,
#   to results/protocol-decompose/lift/: soe and the control as picked (SIME's protocol), with the
#   re-fit continued instead of from scratch (`refit=continue`, the control's too), soe keeping each
#   state's first success instead of `train_0.5` (`select=first_success`) with either re-fit, and soe and
#   the control under the first protocol whole (`protocol=continued`: its 2 / 16 / 8 horizons the one
#   difference from `select=first_success,refit=continue`; a round 0 of its own). Where a seed does not
#   fit a session, decompose-lift-1 runs the six arms on the picked round 0 and decompose-lift-2 the first
#   protocol's two (each its own round 0 and control) into the same results.
# PART decompose-lift-n3: the first protocol's two arms on 3 varied demonstrations (the count the
#   scripted-against-varied campaign had; its other difference from decompose-lift-2 is the evaluation
#   states) to results/protocol-decompose/lift-n3/.
# PART decompose-lift-n3-picked: soe and the control as picked on those 3 demonstrations and states,
#   beside them in results/protocol-decompose/lift-n3/: the protocols compared at the weaker base.
# The parts before main-TASK measure their arms as the `cpu` preset defined them before it took the
# protocol they picked (SIME's on varied demonstrations): under a config whose control arm has either,
# their arms would be others than the committed results', so the script refuses and names the commit
# each part's seeds ran at (c0b0bca; picked-count: 8d0b68b).
# Work directories under WORKDIR (one per part), default $RUNS/protocol (`launch/runs.sh`: RUNS, else
# the main checkout's runs/, never inside a pinned worktree); re-running resumes. CONFIG (default
# configs/lift.py:cpu; the main and rounds parts take configs/TASK.py:PRESET, PRESET default cpu) and
# RESULTS (default results) may be set in the environment, e.g. CONFIG=configs/lift.py:smoke
# PRESET=smoke RESULTS=/tmp/protocol for a quick check.
set -euo pipefail
source "$(dirname "$0")/measured_as.sh"
source "$(dirname "$0")/runs.sh"
parts="sime-count-N, varied-count-N, picked-count-TASK-N, sime-N, style-N, main-TASK[-1|-2|-3], rounds-lift[-1|-2] or decompose-lift[-1|-2|-n3|-n3-picked]"
part=${1:?$parts}
seed=${2:?the training seed}
runs=${3:-$(runs_root)/protocol}
config=${CONFIG:-configs/lift.py:cpu}
out=${RESULTS:-results}
# The first protocol on scripted demonstrations: what the control arm had when the parts before main-TASK ran.
first_protocol=(rounds.refit=continue data.demo_style=scripted)
eval_seed=33333  # the main campaign's evaluation states: used by neither science issue (77777, 55555)
main_arms=(control,dp,sime,soe control,soe_steer control,dp+expert_data,soe+expert_data)
if [[ $part =~ ^main-(lift|can|square)(-([123]))?$ ]]; then
  task=${BASH_REMATCH[1]} nth=${BASH_REMATCH[3]}
  methods=${main_arms[0]},${main_arms[1]#control,},${main_arms[2]#control,}
  [[ -n $nth ]] && methods=${main_arms[nth - 1]}
  python -m soe_jax campaign --config="configs/$task.py:${PRESET:-cpu}" --config.seed="$seed" \
    --config.eval.seed=$eval_seed --methods="$methods" --workdir="$runs/${part#main-}" \
    --results="$out/protocol-main/${part#main-}" --progress=false
  exit
fi
if [[ $part =~ ^picked-count-(lift|can|square)-([0-9]+)$ ]]; then
  task=${BASH_REMATCH[1]} count=${BASH_REMATCH[2]}
  measured_as "configs/$task.py:${PRESET:-cpu}" control 8d0b68b "${first_protocol[@]}"
  python -m soe_jax campaign --config="configs/$task.py:${PRESET:-cpu}" --config.seed="$seed" \
    --config.data.num_demos="$count" --config.rounds.num_rounds=0 --methods=control+protocol=sime+style=varied \
    --workdir="$runs/picked-count-$task-$count" --results="$out/protocol-count/picked-$task-n$count" --progress=false
  exit
fi
if [[ $part =~ ^decompose-lift(-(1|2|n3|n3-picked))?$ ]]; then
  picked=control,soe,control+refit=continue,soe+refit=continue
  picked+=,soe+select=first_success,soe+select=first_success+refit=continue
  first=control+protocol=continued,soe+protocol=continued
  arms=$picked,$first folder=lift demos=()
  case ${BASH_REMATCH[2]} in
    1) arms=$picked ;;
    2) arms=$first ;;
    n3) arms=$first folder=lift-n3 demos=(--config.data.num_demos=3) ;;
    n3-picked) arms=control,soe folder=lift-n3 demos=(--config.data.num_demos=3) ;;
  esac
  python -m soe_jax campaign --config="configs/lift.py:${PRESET:-cpu}" --config.seed="$seed" \
    --config.eval.seed=$eval_seed "${demos[@]}" --methods="$arms" \
    --workdir="$runs/$part" --results="$out/protocol-decompose/$folder" --progress=false
  exit
fi
if [[ $part =~ ^rounds-lift(-([12]))?$ ]]; then
  half=${BASH_REMATCH[2]} rounds_arms=(control,dp,soe control,sime)
  methods=${rounds_arms[0]},${rounds_arms[1]#control,}
  [[ -n $half ]] && methods=${rounds_arms[half - 1]}
  python -m soe_jax campaign --config="configs/lift.py:${PRESET:-cpu}" --config.seed="$seed" \
    --config.eval.seed=$eval_seed --config.rounds.num_rounds=3 --methods="$methods" \
    --workdir="$runs/$part" --results="$out/protocol-rounds/${part#rounds-}" --progress=false
  exit
fi
case ${part%-*} in
  sime-count|varied-count|sime|style) ;;
  *) echo "$part: unknown part ($parts)" >&2
     exit 2 ;;
esac
count=${part##*-}
[[ $count =~ ^[0-9]+$ ]] || { echo "$part: the part ends in its demonstration count, a number" >&2; exit 2; }
measured_as "$config" control c0b0bca "${first_protocol[@]}"
campaign() {  # campaign METHODS NAME RESULTS
  python -m soe_jax campaign --config="$config" --config.seed="$seed" --config.data.num_demos="$count" \
    --methods="$1" --workdir="$runs/$2" --results="$out/$3" --progress=false
}
case ${part%-*} in
  sime-count) campaign control+protocol=sime "sime-count-$count" "protocol-count/sime-n$count" ;;
  varied-count) campaign control+style=varied "varied-count-$count" "protocol-count/varied-n$count" ;;
  sime)
    campaign control+protocol=sime,dp+protocol=sime,sime+protocol=sime,soe+protocol=sime "sime-$count" \
      "protocol-sime/n$count"
    ;;
  style)
    campaign control,dp,sime,soe,control+style=varied,dp+style=varied,sime+style=varied,soe+style=varied \
      "style-$count" "demo-style-campaign/n$count"
    for s in scripted varied; do
      python -m soe_jax latent --config="$config,style=$s" --config.seed="$seed" --config.data.num_demos="$count" \
        --workdir="$runs/style-$count-latent/$s/seed$seed" --progress=false \
        --out="$out/latent-style/lift_n${count}_${s}_seed$seed.json"
    done
    ;;
esac
