#!/usr/bin/env bash
# A state policy for task=open (docs/ARTICULATED_TASKS.md, "A policy"), every step a call of the
# real command line: TRAIN_SCENES kitchens generated with articulated furniture x EPISODES
# demos (CPU executor, no images), their LeRobot dataset, HELDOUT_SCENES more kitchens (other
# seeds, not in the dataset), a diffusion policy on observation.state + environment_state (the
# part's joint and its handle in the robot's base frame) for at most TRAIN_MINUTES, then the
# policy and the planner on the same EVAL_EPISODES configurations of each held-out kitchen
# (evaluation seeds disjoint from the demos'), and the policy on new configurations of its
# training kitchens. A tiny dry run:
#   TRAIN_SCENES=1 HELDOUT_SCENES=1 EPISODES=2 STEPS=4 EVAL_EPISODES=1 RUN=/tmp/op \
#     bash scripts/experiments/open_policy.sh
set -euo pipefail
cd "$(dirname "$0")/../.."

RUN=${RUN:-runs/open_policy}
TASK=${TASK:-open}
TRAIN_SCENES=${TRAIN_SCENES:-8}
HELDOUT_SCENES=${HELDOUT_SCENES:-3}
EPISODES=${EPISODES:-30}
STEPS=${STEPS:-10000}  # about 25 min at 1 thread (6.8 steps/s on this 2-core VM, shared)
TRAIN_MINUTES=${TRAIN_MINUTES:-30}
EVAL_EPISODES=${EVAL_EPISODES:-20}
WORKERS=${WORKERS:-1}
THREADS=${THREADS:-1}
# the U-Net of the CPU state policies (4.4 M parameters: docs/POLICY.md, "Results measured")
TRAIN_OPTIONS=${TRAIN_OPTIONS:-"{diffusion: {down_dims: [64, 128, 256]}}"}
PY=${PY:-python3}
PROMPT="a kitchen where the robot picks up a mug and puts it in the bowl"
COMMON="sim.backend=cpu demos.executor=cpu task=$TASK"
log() { echo "$(date +%T) ${TASK}_policy: $*"; }
t0=$(date +%s)

if [ -f "$RUN/dataset/merged/meta/info.json" ] && [ -f "$RUN/heldout_done" ]; then
  log "1. the data are there ($RUN/dataset/merged)"
else
log "1. $TRAIN_SCENES kitchens x $EPISODES demos, $HELDOUT_SCENES held out"
$PY -m factory stage=generate run_dir="$RUN" "generate.prompts=[$PROMPT]" $COMMON \
  assets.articulated=true generate.render=false generate.scenes_per_prompt="$TRAIN_SCENES" seed=0
$PY -m factory stage=demos run_dir="$RUN" $COMMON demos.render=false \
  demos.episodes_per_scene="$EPISODES" demos.workers="$WORKERS"
$PY -m factory stage=dataset run_dir="$RUN" $COMMON
$PY -m factory stage=generate run_dir="$RUN" "generate.prompts=[$PROMPT]" $COMMON \
  assets.articulated=true generate.render=false generate.scenes_per_prompt="$HELDOUT_SCENES" \
  seed=100000
touch "$RUN/heldout_done"
fi
t1=$(date +%s)

log "2. the state policy: at most $STEPS steps in $TRAIN_MINUTES min"
$PY -m factory stage=train run_dir="$RUN" $COMMON train.inputs=state train.device=cpu \
  train.threads="$THREADS" train.steps="$STEPS" train.max_minutes="$TRAIN_MINUTES" \
  "train.options=$TRAIN_OPTIONS"
t2=$(date +%s)

log "3. evaluation: the policy and the planner, $EVAL_EPISODES configurations per kitchen"
$PY -m factory stage=eval run_dir="$RUN" $COMMON eval.episodes_per_scene="$EVAL_EPISODES" \
  eval.workers="$WORKERS"
$PY -m factory stage=eval run_dir="$RUN" $COMMON eval.policy=planner \
  eval.episodes_per_scene="$EVAL_EPISODES" eval.workers="$WORKERS"
$PY -m factory stage=eval run_dir="$RUN" $COMMON eval.scenes=train eval.episodes_per_scene=5 \
  eval.workers="$WORKERS" eval.name=train_scenes
echo "{\"data_s\": $((t1 - t0)), \"train_s\": $((t2 - t1)), \"eval_s\": $(( $(date +%s) - t2 ))}" \
  > "$RUN/timing.json"
log "done in $(( $(date +%s) - t0 )) s: $RUN/eval/*/results.json"
