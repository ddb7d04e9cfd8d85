#!/usr/bin/env bash
# The mobile camera policy in one GPU session (issue 33, item 6; docs/POLICY.md, "Mobile camera
# policy: one command"), every step a call of the real command line, on one machine (16 cores,
# one GPU), trained the way scripts/experiments/camera_policy.sh trains the fixed-base one:
#
#   1. data: SCENES generated living rooms ("a living room where the robot moves the coke can
#      from the coffee table to the desk", the rooms of scripts/bench_demos.py), EPISODES demos
#      per room of task=mobile_pick_place with the five cameras (left, right, wrist, fisheye
#      front and back; RGB + depth at SIZE x SIZE: the fisheye images are square, so one size
#      for all five) on EXECUTOR (warp with CUDA: the workers plan and simulate, the GPU draws;
#      else cpu), then the merged dataset;
#   2. the image policy (train.inputs=INPUTS, the image recipe of factory/policy/recipe.py:
#      84 px, one observation step, U-Net 128-256-512, EMA; compiled on CUDA, batch BATCH) for
#      TRAIN_MINUTES, its steps set from an assumed rate so that the schedule ends with the
#      time, with the learning curve (train.eval_every_minutes) and, beside it, the planner on
#      the same configurations. train.vision=VISION: perception (default; the fixed task's
#      held-out success went from 0-3 % end to end to 50-58 % with it): a perception network
#      learns the pick object's and the desk's poses from the images (the wrist camera's
#      pixels as points, the other cameras as images; the dataset's
#      observation.environment_state, recorded since schema 6) and lerobot's diffusion policy
#      acts on them and the sub-task; end_to_end: lerobot's image encoder with the auxiliary
#      state loss;
#   3. the final evaluation: EVAL_EPISODES new configurations per training room
#      (eval.scenes=train: the rooms are the training rooms, the configurations are not; the
#      evaluation seeds are eval_seed's hashes offset by EVAL_SEED_OFFSET, disjoint from the
#      demos' episode seeds), success with its Wilson 95 % interval and per sub-task, on the
#      CPU env (the mobile env has no MuJoCo Warp path).
# A tiny dry run on a CPU (1 room, 2 demos at 32 px, 4 training steps, 1 evaluation episode):
#   SCENES=1 EPISODES=2 SIZE=32 TRAIN_MINUTES=0.2 STEPS=4 BATCH=2 EVAL_EPISODES=1 \
#     CURVE_MINUTES=0 EVAL_MAX_STEPS=120 DEVICE=cpu RUN=/tmp/mobcam \
#     bash scripts/experiments/mobile_camera_policy.sh
# Beside camera_policy.sh on one machine: START_AFTER="<files>" waits for one of them before the
# data (e.g. the other script's results/data.json: its data has had the cores; or its gpu_free,
# which also appears if it stops), TRAIN_AFTER="<files>" before the training (its
# results/gpu_free), each at most WAIT_MAX seconds.
# Results: $OUT_DIR (data.json, the training log with its curve, train-<name>.json, the
# evaluations eval-<name>.json and eval-planner.json, summary.json).
set -euo pipefail
cd "$(dirname "$0")/../.."

RUN=${RUN:-runs/mobile_camera}
OUT_DIR=${OUT_DIR:-$RUN/results}
SCENES=${SCENES:-16}
EPISODES=${EPISODES:-20}
SIZE=${SIZE:-64}  # demos.width = demos.height (docs/DEMOS.md's mobile sizes: 64 or 128; 16
# rooms x 20 demos of ~530 frames at 64 px RGB-D of five cameras: ~21 GB in train.video_cache)
FPS=${FPS:-20}  # demos.fps
INPUTS=${INPUTS:-rgbd}  # rgbd or rgb
VISION=${VISION:-perception}  # train.vision: perception or end_to_end (header)
NAME=${NAME:-mobile_$INPUTS}  # the policy's name (policy/<name>, eval/<name>)
BATCH=${BATCH:-512}
TRAIN_MINUTES=${TRAIN_MINUTES:-15}
STEPS=${STEPS:-0}  # 0: from RATE over the minutes left after ~2 of compiling
RATE=${RATE:-9}  # assumed steps/s (the fixed task's 3-camera recipe: 16-17 compiled at batch
# 512 on an H100/H200; five cameras: about 5/3 of its image work)
CURVE_MINUTES=${CURVE_MINUTES:-4}  # 0: no learning curve
CURVE_EPISODES=${CURVE_EPISODES:-2}  # per room
EVAL_EPISODES=${EVAL_EPISODES:-10}  # per room: 160 configurations at the defaults
EVAL_MAX_STEPS=${EVAL_MAX_STEPS:-0}  # eval.max_steps (0: 1.5 x the longest training episode)
DEVICE=${DEVICE:-auto}
EXECUTOR=${EXECUTOR:-}  # demos.executor: empty: warp where CUDA is, else cpu
TRAIN_ARGS=${TRAIN_ARGS:-}  # more train.* overrides (shell-quoted words)
DEMOS_ARGS=${DEMOS_ARGS:-}  # more demos.* overrides (shell-quoted words)
JOBS=${JOBS:-$(getconf _NPROCESSORS_ONLN)}
EVAL_WORKERS=${EVAL_WORKERS:-$(( JOBS * 3 / 4 > 0 ? JOBS * 3 / 4 : 1 ))}
PY=${PY:-python3}
START_AFTER=${START_AFTER:-}  # a file to wait for before the data (header)
TRAIN_AFTER=${TRAIN_AFTER:-}  # a file to wait for before the training (header)
WAIT_MAX=${WAIT_MAX:-3600}  # seconds at most for each
if [ -z "$EXECUTOR" ]; then  # warp where CUDA is (docs/DEMOS.md, "The GPU path"), else cpu
  EXECUTOR=$($PY -c "import torch; print('warp' if torch.cuda.is_available() else 'cpu')" \
    2>/dev/null || echo cpu)
fi
TASK="task=mobile_pick_place"
PROMPT="a living room where the robot moves the coke can from the coffee table to the desk"
mkdir -p "$RUN" "$OUT_DIR"
rm -f "$RUN/exit_status"
trap 'echo $? > "$RUN/exit_status"' EXIT  # for whoever watches: the script ended, and how
log() { echo "$(date +%T) mobile camera: $*"; }

wait_for() {  # wait_for "<files>": until one of them exists, at most WAIT_MAX seconds
  [ -n "$1" ] || return 0
  local waited=0 f
  log "   waiting for $1"
  while [ "$waited" -lt "$WAIT_MAX" ]; do
    for f in $1; do [ ! -e "$f" ] || { log "   waited $waited s for $f"; return 0; }; done
    sleep 5; waited=$(( waited + 5 ))
  done
  log "   gave up waiting after $waited s"
}

wait_for "$START_AFTER"
t0=$(date +%s)
log "1. $SCENES living rooms x $EPISODES demos, five cameras at $SIZE px ($EXECUTOR executor, $JOBS cores)"
shards=$(( SCENES < JOBS ? SCENES : JOBS )) pids=()
for i in $(seq 0 $((shards - 1))); do  # one shard per core
  $PY -m factory stage=generate run_dir="$RUN" "generate.prompts=[$PROMPT]" sim.backend=cpu \
    generate.scenes_per_prompt="$SCENES" generate.render=false seed=0 \
    shard.index="$i" shard.count="$shards" &
  pids+=($!)
done
wait "${pids[@]}"
t_gen=$(date +%s)
demos_workers=$JOBS
[ "$EXECUTOR" != warp ] || demos_workers=$(( JOBS > 1 ? JOBS - 1 : 1 ))  # one core draws
eval "demos_extra=($DEMOS_ARGS)"
$PY -m factory stage=demos run_dir="$RUN" $TASK sim.backend=cpu demos.executor="$EXECUTOR" \
  demos.episodes_per_scene="$EPISODES" demos.workers="$demos_workers" \
  demos.width="$SIZE" demos.height="$SIZE" demos.fps="$FPS" "${demos_extra[@]}"
t_demos=$(date +%s)
$PY -m factory stage=dataset run_dir="$RUN" $TASK dataset.workers="$JOBS"
t_data=$(date +%s)
echo "{\"generate_seconds\": $(( t_gen - t0 )), \"demos_seconds\": $(( t_demos - t_gen )), \
\"dataset_seconds\": $(( t_data - t_demos )), \"executor\": \"$EXECUTOR\", \"size\": $SIZE}" \
  > "$OUT_DIR/data.json"
cp "$RUN"/episodes/summary-*.json "$OUT_DIR/" 2>/dev/null || true

if [ "$STEPS" = 0 ]; then
  STEPS=$($PY -c "import sys; r, m = map(float, sys.argv[1:]); print(int(r * 0.9 * 60 * max(m - 2.0, 0.5)))" \
    "$RATE" "$TRAIN_MINUTES")
fi
EVAL_COMMON="$TASK sim.backend=cpu eval.scenes=train eval.max_steps=$EVAL_MAX_STEPS"
log "2. $NAME ($INPUTS, $VISION): $STEPS steps, at most $TRAIN_MINUTES min, batch $BATCH; the planner beside"
$PY -m factory stage=eval run_dir="$RUN" $EVAL_COMMON eval.policy=planner eval.name=planner \
  eval.episodes_per_scene="$EVAL_EPISODES" eval.workers=3 eval.batch=8 eval.videos=0 \
  > "$OUT_DIR/planner.log" 2>&1 &
PLANNER=$!
eval "train_extra=($TRAIN_ARGS)"
curve_device=$DEVICE  # the curve's inference on GPU 1 of a two-GPU machine, off the training's
# GPU (camera_policy.sh's reason: each curve process time-slices the GPU it runs on)
if [ "$DEVICE" != cpu ] && [ "$(nvidia-smi -L 2>/dev/null | wc -l)" -gt 1 ]; then curve_device=cuda:1; fi
wait_for "$TRAIN_AFTER"
t1=$(date +%s)
$PY -m factory stage=train run_dir="$RUN" $EVAL_COMMON train.name="$NAME" train.inputs="$INPUTS" \
  train.vision="$VISION" train.video_cache=memory \
  train.steps="$STEPS" train.batch_size="$BATCH" train.max_minutes="$TRAIN_MINUTES" \
  train.device="$DEVICE" train.save_every=1000 train.log_every=100 \
  train.eval_every_minutes="$CURVE_MINUTES" train.eval_episodes="$CURVE_EPISODES" \
  eval.workers=$(( EVAL_WORKERS / 2 > 0 ? EVAL_WORKERS / 2 : 1 )) eval.batch=8 \
  eval.device="$curve_device" "${train_extra[@]}" || log "   the training failed"
t_train=$(date +%s)
log "   trained in $(( t_train - t1 )) s"
cp "$RUN/policy/$NAME/train_log.jsonl" "$OUT_DIR/train_log-$NAME.jsonl" || true
cp "$RUN/policy/$NAME/train.json" "$OUT_DIR/train-$NAME.json" || true

log "3. final evaluation: $EVAL_EPISODES new configurations per training room"
$PY -m factory stage=eval run_dir="$RUN" $EVAL_COMMON eval.policy="$NAME" \
  eval.episodes_per_scene="$EVAL_EPISODES" eval.device="$DEVICE" eval.videos=2 \
  eval.workers="$EVAL_WORKERS" eval.batch=8 || log "   the evaluation failed"
t_eval=$(date +%s)
log "   evaluated in $(( t_eval - t_train )) s"
wait "$PLANNER" || log "   the planner evaluation failed: $OUT_DIR/planner.log"
for d in "$RUN"/eval/*/; do
  [ -f "$d/results.json" ] && cp "$d/results.json" "$OUT_DIR/eval-$(basename "$d").json"
done
$PY - "$OUT_DIR" "$NAME" "$(( t_train - t1 ))" "$(( t_eval - t_train ))" "$(( $(date +%s) - t0 ))" <<'EOF'
import json, sys
from pathlib import Path
out, name = Path(sys.argv[1]), sys.argv[2]
summary = {"train_seconds": int(sys.argv[3]), "eval_seconds": int(sys.argv[4]),
           "total_seconds": int(sys.argv[5])}
for key in (name, "planner"):
    p = out / f"eval-{key}.json"
    if p.is_file():
        r = json.loads(p.read_text())
        summary[key] = {k: r.get(k) for k in ("success_rate", "ci95", "episodes", "successes",
                                             "failures", "per_subtask")}
        lo, hi = r["ci95"]
        print(f"{key}: {r['successes']} of {r['episodes']} = {100 * r['success_rate']:.1f} % "
              f"(95 % CI {100 * lo:.1f}-{100 * hi:.1f} %), failures {r['failures']}")
(out / "summary.json").write_text(json.dumps(summary, indent=1))
EOF
log "done in $(( $(date +%s) - t0 )) s"
