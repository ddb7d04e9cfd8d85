#!/usr/bin/env bash
# The policy experiment of docs/POLICY.md, end to end on one machine (the H100 node: 16 cores,
# one GPU), every step a call of the real command line:
#
#   1. data: TRAIN_SCENES generated kitchens with the pick-and-place task (one generate shard
#      per core), EPISODES demos per scene, the merged LeRobot dataset; then HELDOUT_SCENES
#      more kitchens (other seeds) that are not in the dataset: the held-out scenes;
#   2. the scaling curve: state-input diffusion policies trained on the GPU on 1, 2, 4, ...
#      scenes, evaluated on the held-out scenes with the planner as the reference
#      (scripts/scaling_policy.py); beside them a state policy trained on the CPU (2 threads),
#      evaluated on the held-out scenes and on new configurations of its training scenes;
#   3. the paper's setting: an RGB-D diffusion policy (three cameras + end-effector pose) trained
#      on the GPU for RGBD_STEPS steps, evaluated on the held-out scenes.
#
# Training is bounded by steps and, where *_MINUTES > 0, by wall-clock minutes (train.max_minutes).
# Sizes come from the environment (defaults: the run quoted in docs/POLICY.md); a tiny dry run:
#   TRAIN_SCENES=2 HELDOUT_SCENES=1 EPISODES=2 POINTS="1 2" STATE_STEPS=20 RGBD_STEPS=4 \
#     EVAL_EPISODES=2 RUN=/tmp/tiny bash scripts/experiments/policy_experiment.sh
# Results: $RUN/eval/*/results.json, $OUT_DIR/*.json (scaling JSON + SVG, the summaries).
# On the GPU machine: scripts/gpu_bundle.sh gathers the wheels, GL loaders and robot models it
# needs into one tar and prints the line that installs it there (scripts/gpu_install.sh, which
# also uninstalls its preinstalled transformers: it needs a newer huggingface_hub than lerobot
# 0.4.4 pins).
# Run this script there in the background (setsid) and copy results under $OUT in every call:
# an idle machine is given back after 30 s with everything on it.
set -euo pipefail
cd "$(dirname "$0")/../.."

RUN=${RUN:-runs/policy}
OUT_DIR=${OUT_DIR:-$RUN/results}
TRAIN_SCENES=${TRAIN_SCENES:-16}
HELDOUT_SCENES=${HELDOUT_SCENES:-5}  # about 1 kitchen in 4 cannot host the task (skipped)
EPISODES=${EPISODES:-24}
POINTS=${POINTS:-1 2 4 8 16}
STATE_STEPS=${STATE_STEPS:-20000}
STATE_MINUTES=${STATE_MINUTES:-0}
STATE_BATCH=${STATE_BATCH:-64}
SCALE_BATCH=${SCALE_BATCH:-256}
CPU_STEPS=${CPU_STEPS:-20000}
CPU_MINUTES=${CPU_MINUTES:-0}
RGBD_STEPS=${RGBD_STEPS:-6000}
RGBD_MINUTES=${RGBD_MINUTES:-0}
RGBD_BATCH=${RGBD_BATCH:-32}
RGBD_WORKERS=${RGBD_WORKERS:-6}
EVAL_EPISODES=${EVAL_EPISODES:-30}
RGBD_EVAL_EPISODES=${RGBD_EVAL_EPISODES:-90}
RGBD_EVAL_WORKERS=${RGBD_EVAL_WORKERS:-$(( $(getconf _NPROCESSORS_ONLN) * 3 / 4 ))}  # eval.workers
RGBD_EVAL_BATCH=${RGBD_EVAL_BATCH:-8}
PLANNER_WORKERS=${PLANNER_WORKERS:-4}
CPU_STATE=${CPU_STATE:-1}
SCALING=${SCALING:-1}  # 0: no scaling curve (e.g. an RGB-D-only run)
RGBD=${RGBD:-1}  # 0: no RGB-D policy (then DEMOS_ARGS=demos.render=false makes the data much faster)
DEMOS_ARGS=${DEMOS_ARGS:-}
TRAIN_CONFIGS=${TRAIN_CONFIGS:-5}
JOBS=${JOBS:-$(getconf _NPROCESSORS_ONLN)}
PY=${PY:-python3}
PROMPT="a kitchen where the robot picks up a mug and puts it in the bowl"
DDIM='noise_scheduler_type: DDIM, num_inference_steps: 10'
STATE_OPTS="train.options={diffusion: {down_dims: [128, 256, 512], horizon: 16, n_action_steps: 8, $DDIM}}"
RGBD_OPTS=${RGBD_OPTS:-"train.options={diffusion: {$DDIM}}"}
RGBD_ARGS=${RGBD_ARGS:-}  # more train.* overrides of the RGB-D policy (word-split), e.g. train.lr=3e-4
CPU_OPTS=${CPU_OPTS:-"train.options={diffusion: {down_dims: [64, 128, 256], horizon: 16, n_action_steps: 8, diffusion_step_embed_dim: 64, $DDIM}}"}
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
$PY -m factory stage=demos run_dir="$RUN" demos.episodes_per_scene="$EPISODES" demos.workers="$JOBS" $DEMOS_ARGS
$PY -m factory stage=dataset run_dir="$RUN" dataset.workers="$JOBS"
log "   $HELDOUT_SCENES held-out kitchens"
generate "$HELDOUT_SCENES" 100000
echo "{\"data_seconds\": $(( $(date +%s) - t0 ))}" > "$OUT_DIR/data.json"

log "2. scaling curve (state, GPU), the CPU state policy and 3. RGB-D (GPU), side by side"
t1=$(date +%s)
HELD=${HELDOUT_IDS:+"eval.scenes=[${HELDOUT_IDS// /,}]"}
rgbd() {  # the planner on the same configurations runs beside the training (it needs no policy)
  $PY -m factory stage=eval run_dir="$RUN" eval.policy=planner eval.episodes_per_scene="$RGBD_EVAL_EPISODES" \
    eval.name=planner_rgbd eval.workers="$PLANNER_WORKERS" eval.batch="$RGBD_EVAL_BATCH" eval.videos=0 \
    $HELD > "$OUT_DIR/planner-rgbd.log" 2>&1 &
  local planner=$!
  $PY -m factory stage=train run_dir="$RUN" train.name=rgbd train.inputs=rgbd \
    train.steps="$RGBD_STEPS" train.batch_size="$RGBD_BATCH" train.num_workers="$RGBD_WORKERS" \
    train.save_every=1000 train.log_every=50 train.device=auto train.max_minutes="$RGBD_MINUTES" \
    "$RGBD_OPTS" $RGBD_ARGS
  log "   RGB-D trained in $(( $(date +%s) - t1 )) s"
  $PY -m factory stage=eval run_dir="$RUN" eval.policy=rgbd eval.episodes_per_scene="$RGBD_EVAL_EPISODES" \
    eval.device=auto eval.videos=2 eval.workers="$RGBD_EVAL_WORKERS" eval.batch="$RGBD_EVAL_BATCH" $HELD
  log "   RGB-D evaluated in $(( $(date +%s) - t1 )) s"
  wait "$planner" || log "   the planner evaluation failed: $OUT_DIR/planner-rgbd.log"
}
cpu_state() {  # trained on the CPU with 2 threads, evaluated on held-out and training scenes
  $PY -m factory stage=train run_dir="$RUN" train.name=state_cpu train.inputs=state \
    train.device=cpu train.threads=2 train.steps="$CPU_STEPS" train.batch_size="$STATE_BATCH" \
    train.max_minutes="$CPU_MINUTES" train.save_every=500 train.log_every=50 "$CPU_OPTS"
  log "   CPU state policy trained in $(( $(date +%s) - t1 )) s"
  OMP_NUM_THREADS=2 $PY -m factory stage=eval run_dir="$RUN" eval.policy=state_cpu \
    eval.episodes_per_scene="$EVAL_EPISODES" eval.device=cpu eval.nthread=2 eval.videos=1 $HELD
  OMP_NUM_THREADS=2 $PY -m factory stage=eval run_dir="$RUN" eval.policy=state_cpu eval.scenes=train \
    eval.name=state_cpu_train_scenes eval.episodes_per_scene="$TRAIN_CONFIGS" eval.device=cpu \
    eval.nthread=2 eval.videos=1
}
RGBD_PID=""
if [ "$RGBD" = 1 ]; then
  rgbd > "$OUT_DIR/rgbd.log" 2>&1 &
  RGBD_PID=$!
fi
CPU_PID=""
if [ "$CPU_STATE" = 1 ]; then
  cpu_state > "$OUT_DIR/state-cpu.log" 2>&1 &
  CPU_PID=$!
fi
if [ "$SCALING" = 1 ]; then
  npoints=$(wc -w <<< "$POINTS")
  $PY scripts/scaling_policy.py --run-dir "$RUN" --points $POINTS --steps "$STATE_STEPS" \
    --batch-size "$SCALE_BATCH" --device auto --episodes "$EVAL_EPISODES" \
    --parallel "$((npoints + 1))" --threads 2 --train-arg "$STATE_OPTS" \
    --train-arg train.log_every=100 --train-arg train.max_minutes="$STATE_MINUTES" \
    --train-arg train.save_every=2000 --tag "$(basename "$RUN")" \
    --out "$OUT_DIR/scaling.json" --plot "$OUT_DIR/scaling.svg" ${HELDOUT_IDS:+--heldout $HELDOUT_IDS} \
    > "$OUT_DIR/scaling.log" 2>&1 || log "   the scaling script failed: $OUT_DIR/scaling.log"
fi
log "   scaling done in $(( $(date +%s) - t1 )) s"
[ -z "$CPU_PID" ] || wait "$CPU_PID" || log "   the CPU state policy failed: $OUT_DIR/state-cpu.log"
[ -z "$RGBD_PID" ] || wait "$RGBD_PID" || log "   RGB-D failed: $OUT_DIR/rgbd.log"
for d in "$RUN"/eval/*/; do if [ -f "$d/results.json" ]; then cp "$d/results.json" "$OUT_DIR/eval-$(basename "$d").json"; fi; done
for d in "$RUN"/policy/*/; do
  cp "$d/train.json" "$OUT_DIR/train-$(basename "$d").json" || true
  cp "$d/train_log.jsonl" "$OUT_DIR/train_log-$(basename "$d").jsonl" || true
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
