#!/usr/bin/env bash
# The policy experiment of docs/POLICY.md, end to end on one machine (the H100 node: 16 cores,
# one GPU), every step a call of the real command line:
#
#   1. data: TRAIN_SCENES generated kitchens with the pick-and-place task (one generate shard
#      per core), EPISODES demos per scene, the merged LeRobot dataset; then HELDOUT_SCENES
#      more kitchens (other seeds) that are not in the dataset: the held-out scenes;
#   2. the scaling curve: state-input diffusion policies trained on the CPU (2 cores each,
#      taskset) on 1, 2, 4, ... scenes, evaluated on the held-out scenes with the planner as the
#      reference (scripts/scaling_policy.py); the largest point is the CPU state policy, also
#      evaluated on new configurations of its training scenes;
#   3. the paper's setting: an RGB-D diffusion policy (three cameras + end-effector pose) trained
#      on the GPU for RGBD_STEPS steps, evaluated on the held-out scenes.
#
# Training is bounded by steps and, where *_MINUTES > 0, by wall-clock minutes (train.max_minutes).
# Sizes come from the environment (defaults: the run quoted in docs/POLICY.md); a tiny dry run:
#   TRAIN_SCENES=2 HELDOUT_SCENES=1 EPISODES=2 POINTS="1 2" STATE_STEPS=20 RGBD_STEPS=4 \
#     EVAL_EPISODES=2 RUN=/tmp/tiny bash scripts/experiments/policy_experiment.sh
# Results: $RUN/eval/*/results.json, $OUT_DIR/*.json (scaling JSON + SVG, the summaries).
set -euo pipefail
cd "$(dirname "$0")/../.."

RUN=${RUN:-runs/policy}
OUT_DIR=${OUT_DIR:-$RUN/results}
TRAIN_SCENES=${TRAIN_SCENES:-16}
HELDOUT_SCENES=${HELDOUT_SCENES:-3}
EPISODES=${EPISODES:-24}
POINTS=${POINTS:-1 2 4 8 16}
STATE_STEPS=${STATE_STEPS:-8000}
STATE_MINUTES=${STATE_MINUTES:-0}
STATE_BATCH=${STATE_BATCH:-64}
RGBD_STEPS=${RGBD_STEPS:-6000}
RGBD_MINUTES=${RGBD_MINUTES:-0}
RGBD_BATCH=${RGBD_BATCH:-32}
RGBD_WORKERS=${RGBD_WORKERS:-6}
EVAL_EPISODES=${EVAL_EPISODES:-30}
TRAIN_CONFIGS=${TRAIN_CONFIGS:-5}
JOBS=${JOBS:-$(getconf _NPROCESSORS_ONLN)}
PY=${PY:-python3}
PROMPT="a kitchen where the robot picks up a mug and puts it in the bowl"
STATE_OPTS='train.options={diffusion: {down_dims: [128, 256, 512], horizon: 16, n_action_steps: 8}}'
mkdir -p "$RUN" "$OUT_DIR"
log() { echo "$(date +%T) experiment: $*"; }

generate() {  # generate <count> <seed>: kitchens, one shard per core
  local n=$1 seed=$2 shards=$(( $1 < JOBS ? $1 : JOBS ))
  for i in $(seq 0 $((shards - 1))); do
    $PY -m factory stage=generate run_dir="$RUN" "generate.prompts=[$PROMPT]" \
      generate.scenes_per_prompt="$n" seed="$seed" shard.index="$i" shard.count="$shards" &
  done
  wait
}

t0=$(date +%s)
log "1. $TRAIN_SCENES training kitchens"
generate "$TRAIN_SCENES" 0
$PY -m factory stage=demos run_dir="$RUN" demos.episodes_per_scene="$EPISODES" demos.workers="$JOBS"
$PY -m factory stage=dataset run_dir="$RUN" dataset.workers="$JOBS"
log "   $HELDOUT_SCENES held-out kitchens"
generate "$HELDOUT_SCENES" 100000
echo "{\"data_seconds\": $(( $(date +%s) - t0 ))}" > "$OUT_DIR/data.json"

log "2. scaling curve (state, CPU) and 3. RGB-D (GPU), side by side"
t1=$(date +%s)
rgbd() {
  $PY -m factory stage=train run_dir="$RUN" train.name=rgbd train.inputs=rgbd \
    train.steps="$RGBD_STEPS" train.batch_size="$RGBD_BATCH" train.num_workers="$RGBD_WORKERS" \
    train.save_every=1000 train.log_every=50 train.device=auto train.max_minutes="$RGBD_MINUTES"
}
rgbd > "$OUT_DIR/rgbd-train.log" 2>&1 &
RGBD_PID=$!
# the state points: 2 cores each (taskset inside scaling_policy's jobs through OMP threads = 2)
npoints=$(wc -w <<< "$POINTS")
$PY scripts/scaling_policy.py --run-dir "$RUN" --points $POINTS --steps "$STATE_STEPS" \
  --batch-size "$STATE_BATCH" --device cpu --episodes "$EVAL_EPISODES" --parallel "$((npoints + 1))" \
  --threads 2 --train-arg "$STATE_OPTS" --train-arg train.log_every=100 \
  --train-arg train.max_minutes="$STATE_MINUTES" \
  --train-arg train.save_every=1000 --tag "$(basename "$RUN")" \
  --out "$OUT_DIR/scaling.json" --plot "$OUT_DIR/scaling.svg" > "$OUT_DIR/scaling.log" 2>&1
log "   scaling done in $(( $(date +%s) - t1 )) s"
last=$(printf 'scale_diffusion_state_%03d' "$(tr ' ' '\n' <<< "$POINTS" | sort -n | tail -1)")
$PY -m factory stage=eval run_dir="$RUN" eval.policy="$last" eval.scenes=train \
  eval.episodes_per_scene="$TRAIN_CONFIGS" eval.device=cpu eval.videos=1 \
  > "$OUT_DIR/state-train-scenes.log" 2>&1
wait "$RGBD_PID"
log "   RGB-D trained in $(( $(date +%s) - t1 )) s"
$PY -m factory stage=eval run_dir="$RUN" eval.policy=rgbd eval.episodes_per_scene="$EVAL_EPISODES" \
  eval.device=auto eval.videos=2 > "$OUT_DIR/rgbd-eval.log" 2>&1
for d in "$RUN"/eval/*/; do cp "$d/results.json" "$OUT_DIR/eval-$(basename "$d").json"; done
for d in "$RUN"/policy/*/; do
  cp "$d/train.json" "$OUT_DIR/train-$(basename "$d").json"
  cp "$d/train_log.jsonl" "$OUT_DIR/train_log-$(basename "$d").jsonl"
done
if [ "${BENCH:-0}" = 1 ]; then
  log "4. bench_policy (training steps/s, rollouts/min, memory)"
  $PY scripts/bench_policy.py --run-dir "$RUN" --inputs state --device cpu --threads 2 \
    --options '{"diffusion": {"down_dims": [128, 256, 512], "horizon": 16, "n_action_steps": 8}}' \
    --nthread 2 --tag node-2threads --out "$OUT_DIR/bench-state-cpu.json" > "$OUT_DIR/bench.log" 2>&1 || true
  $PY scripts/bench_policy.py --run-dir "$RUN" --inputs state --device cuda --batch-size 256 \
    --options '{"diffusion": {"down_dims": [128, 256, 512], "horizon": 16, "n_action_steps": 8}}' \
    --nthread 16 --episodes 8 --tag h100 --out "$OUT_DIR/bench-state-cuda.json" >> "$OUT_DIR/bench.log" 2>&1 || true
  $PY scripts/bench_policy.py --run-dir "$RUN" --inputs rgbd --device cuda --batch-size 32 \
    --workers "$RGBD_WORKERS" --nthread 16 --episodes 8 --tag h100 \
    --out "$OUT_DIR/bench-rgbd-cuda.json" >> "$OUT_DIR/bench.log" 2>&1 || true
fi
log "done in $(( $(date +%s) - t0 )) s"
