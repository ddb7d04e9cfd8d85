#!/usr/bin/env bash
# The paper's camera policy in one GPU session (docs/POLICY.md, "The paper's setting"), every
# step a call of the real command line, on one machine (16 cores, one GPU):
#
#   1. the recipe's speed (scripts/bench_policy.py --variants rgbd-speed) on the small dataset
#      BENCH_DATASET (skipped if empty): lerobot's preset with the DataLoader first, alone,
#      then the rest beside step 2 (pinned to 3 cores; a clean figure needs a machine doing
#      nothing else: benchmarks/results/policy-speed-rgbd-h100-bare.json);
#   2. data: TRAIN_SCENES generated kitchens x EPISODES demos with RGB-D rendering (CPU
#      executor: a bare GPU machine would spend minutes compiling Warp kernels), the merged
#      dataset, and HELDOUT_SCENES more kitchens (other seeds) that are not in it;
#   3. the RGB-D policy with the default image recipe (factory/policy/recipe.py; compiled on
#      CUDA, batch BATCH) for TRAIN_MINUTES, its steps set from the rate so that the schedule ends
#      with the time, with the learning curve (train.eval_every_minutes) and, beside it, the
#      planner on the same held-out configurations;
#   4. the final evaluation: EVAL_EPISODES configurations per held-out kitchen.
# With SECOND_GPU (a two-GPU machine), a second policy trains and is evaluated the same way at
# the same time on that GPU: the other input kind (rgb beside rgbd), or a variant of the recipe
# (SECOND_NAME=rgbd128 SECOND_INPUTS=rgbd SECOND_ARGS='train.options={diffusion: {resize_shape:
# [128, 128]}}'): two recipes for the device time of one on a machine that counts in full.
# The shading augmentation's A/B on both envs (the renderers' disagreement, docs/POLICY.md):
#   SECOND_GPU=1 SECOND_NAME=rgbd_shaded SECOND_INPUTS=rgbd SECOND_ARGS='train.augment_shading=0.15'
#   EVAL_WARP=1 (with SECOND_GPU the second policy is evaluated on MuJoCo Warp too, after the first)
# With EVAL_WARP=1 (and WARP_WARM, the default) the held-out kitchens' MuJoCo Warp kernels are
# compiled during the training; when the training ends, the recorded episodes of the first REPLAY_SCENES
# training kitchens are replayed and the policy is evaluated on the same held-out
# configurations with eval.executor=warp (each timed, the policy first: the env preloads its
# kernels, and results.json's timing_this_call and the log's per-scene lines say where the time
# went; WARP_PLANNER=1 adds the planner), beside the CPU env's
# evaluation of the policy and of the same replays (on the cores the Warp processes leave: the CPU
# env's evaluations are pinned off the first 2 x WARP_WORKERS cores and, on a two-GPU machine
# without SECOND_GPU, run their policies on GPU 1), for the agreement: one session's device time
# holds both.
# $OUT_DIR/gpu_free appears when this script no longer needs the GPU (another script on the
# machine may wait for it: mobile_camera_policy.sh's TRAIN_AFTER).
#
# With VISION=perception (factory/policy/perception.py) the policy is a perception network and a
# lerobot state policy; PERCEPTION_CHECK=3 then records 3 demos per held-out kitchen into a run of
# their own and measures the perception's position errors there and on the training frames. The
# next comparison, on a two-GPU machine (the wrist camera alone: the one whose pose is known):
#   VISION=perception PERCEPTION_CHECK=3 SECOND_GPU=1 SECOND_NAME=rgbd_wrist SECOND_INPUTS=rgbd \
#     SECOND_ARGS="'train.cameras=[wrist]'" TRAIN_MINUTES=12 bash scripts/experiments/camera_policy.sh
# A tiny dry run on a CPU:
#   TRAIN_SCENES=1 HELDOUT_SCENES=1 EPISODES=2 TRAIN_MINUTES=0.2 STEPS=4 BATCH=2 \
#     EVAL_EPISODES=1 CURVE_MINUTES=0.05 CURVE_EPISODES=1 BENCH_DATASET= DEVICE=cpu \
#     RUN=/tmp/cam bash scripts/experiments/camera_policy.sh
# Results: $OUT_DIR (the variants, the training log with its curve, the evaluations).
set -euo pipefail
cd "$(dirname "$0")/../.."

RUN=${RUN:-runs/camera}
OUT_DIR=${OUT_DIR:-$RUN/results}
TRAIN_SCENES=${TRAIN_SCENES:-16}
HELDOUT_SCENES=${HELDOUT_SCENES:-3}
EPISODES=${EPISODES:-30}
INPUTS=${INPUTS:-rgbd}
VISION=${VISION:-perception}  # train.vision: perception (factory/policy/perception.py; 58 % held
# out on a bare H200, docs/POLICY.md) or end_to_end (lerobot's image encoder: 0-3 %)
BATCH=${BATCH:-512}
TRAIN_MINUTES=${TRAIN_MINUTES:-15}
STEPS=${STEPS:-0}  # 0: from the rate of the recipe (step 1's measure, else 11 or 17 steps/s)
CURVE_MINUTES=${CURVE_MINUTES:-3.5}
CURVE_EPISODES=${CURVE_EPISODES:-10}
EVAL_EPISODES=${EVAL_EPISODES:-90}
DEVICE=${DEVICE:-auto}
BENCH_DATASET=${BENCH_DATASET:-}
SECOND_GPU=${SECOND_GPU:-}  # e.g. 1: a second policy trains on that GPU
SECOND_INPUTS=${SECOND_INPUTS:-$([ "$INPUTS" = rgb ] && echo rgbd || echo rgb)}  # its inputs
SECOND_NAME=${SECOND_NAME:-$SECOND_INPUTS}  # its name (policy/<name>, eval/<name>)
SECOND_ARGS=${SECOND_ARGS:-}  # more train.* overrides of the second policy (shell-quoted words)
SECOND_VISION=${SECOND_VISION:-$VISION}  # its train.vision
EVAL_WARP=${EVAL_WARP:-}  # 1: replays and the policy on MuJoCo Warp too (header)
REPLAY_SCENES=${REPLAY_SCENES:-3}  # with EVAL_WARP: training kitchens replayed on both executors
WARP_PLANNER=${WARP_PLANNER:-}  # 1 (with EVAL_WARP): the planner on MuJoCo Warp as well
WARP_OPENGL=${WARP_OPENGL:-}  # N (with EVAL_WARP): the policy on the first N configurations per
# held-out kitchen with eval.executor=warp_opengl (Warp's physics, OpenGL's cameras), after the
# Warp evaluation: paired with the cpu and warp verdicts it splits their disagreement into the
# renderer's share and the physics' (docs/POLICY.md)
WARP_WARM=${WARP_WARM-1}  # with EVAL_WARP: during the training, the held-out kitchens' MuJoCo Warp
# kernels compiled into the kernel cache by an evaluation of the policy's first checkpoint on
# MuJoCo Warp, 1 episode of 2 frames per kitchen (its cameras, depth and image size: the final
# evaluation's kernels; 2 cores, its inference on the CPU; GPU 1 of a two-GPU machine), so that
# the final Warp evaluation reads them (bare H200, 2026-11-29: its 3 processes spent 97-123 s
# each compiling them); WARP_WARM= for a cold one
WARP_WORKERS=${WARP_WORKERS:-3}  # processes driving the GPU for the policy (a scene each at a
# time: one's host work overlaps another's launches); the replay builds the kernels in one
ENSEMBLE_AB=${ENSEMBLE_AB:-}  # 1: the final evaluation also without temporal ensembling
# (eval.ensemble=-1, eval/<inputs>-plain), on the same configurations, beside the default
ENSEMBLE_KS=${ENSEMBLE_KS:-$([ -n "$ENSEMBLE_AB" ] && echo -1 || true)}  # eval.ensemble
# values evaluated beside the default (e.g. "-1 0.3": eval/<inputs>-plain, eval/<inputs>-k0.3)
KS_EPISODES=${KS_EPISODES:-$EVAL_EPISODES}  # their configurations per held-out kitchen (the
# first of the default's: the same seeds)
EVAL_ARGS=${EVAL_ARGS:-}  # more eval.* overrides of every final evaluation of the policy, CPU
# and Warp (shell-quoted words), e.g. eval.ensemble_every=2
EXPORT_PARTS=${EXPORT_PARTS:-}  # e.g. 15M: once trained, $OUT_DIR/policy-<name>.tar.partNN, the
# policy's pretrained_model (with the perception's files) and train.json in pieces of that size,
# for a machine whose files come back one size-limited file at a time (cat the parts, untar)
PERCEPTION_CHECK=${PERCEPTION_CHECK:-}  # N (VISION=perception): N demos per held-out kitchen,
# recorded after the evaluation into their own run, to measure the perception's errors there
BENCH_STEPS=${BENCH_STEPS:-150}
TAG=${TAG:-gpu}
JOBS=${JOBS:-$(getconf _NPROCESSORS_ONLN)}
EVAL_WORKERS=${EVAL_WORKERS:-$(( JOBS * 3 / 4 ))}
PY=${PY:-python3}
DEMOS_ARGS=${DEMOS_ARGS-demos.appearance.scene_camera_pos=0.05 demos.appearance.scene_camera_angle=10}
# more demos.* overrides of the training data (shell-quoted words; the default: the left and right
# cameras jittered by up to 5 cm and 10 deg per episode, 57.8 % held out on a bare H200 against
# 47.0 % with the 1 cm / 1.5 deg of every camera; DEMOS_ARGS= for those)
COMMON="sim.backend=cpu demos.executor=cpu"
PROMPT="a kitchen where the robot picks up a mug and puts it in the bowl"
mkdir -p "$RUN" "$OUT_DIR"
rm -f "$RUN/exit_status" "$OUT_DIR/gpu_free"
trap 'echo $? > "$RUN/exit_status"; touch "$OUT_DIR/gpu_free"' EXIT  # for whoever watches:
# the script ended, and how; and it no longer needs the GPU
log() { echo "$(date +%T) camera: $*"; }
pin() {  # pin <cores> <command...>: taskset where there are cores to spare
  if command -v taskset >/dev/null && [ "$JOBS" -gt 6 ]; then taskset -c "$1" "${@:2}"; else "${@:2}"; fi
}

generate() {  # generate <count> <seed>: kitchens, one shard per core (the data's cores)
  local n=$1 seed=$2 shards=$(( $1 < JOBS ? $1 : JOBS )) pids=()
  for i in $(seq 0 $((shards - 1))); do
    pin "$DATA_PIN" $PY -m factory stage=generate run_dir="$RUN" "generate.prompts=[$PROMPT]" $COMMON \
      generate.scenes_per_prompt="$n" seed="$seed" shard.index="$i" shard.count="$shards" &
    pids+=($!)
  done
  wait "${pids[@]}"  # its own shards only, not the benchmark running beside
}

t0=$(date +%s)
BENCH_PID=""
if [ -n "$BENCH_DATASET" ]; then
  log "1. the recipe's speed on $BENCH_DATASET (the baseline alone)"
  bench=($PY scripts/bench_policy.py --run-dir "$RUN" --dataset "$BENCH_DATASET" --inputs rgbd
    --device cuda --steps "$BENCH_STEPS" --tag "$TAG")
  "${bench[@]}" --variants rgbd-baseline --out "$OUT_DIR/variants-baseline.json" \
    > "$OUT_DIR/bench.log" 2>&1 || log "   the baseline failed: $OUT_DIR/bench.log"
  pin 0-2 "${bench[@]}" --variants rgbd-speed --out "$OUT_DIR/variants.json" \
    >> "$OUT_DIR/bench.log" 2>&1 &
  BENCH_PID=$!
  DATA_CORES=$(( JOBS > 6 ? JOBS - 3 : JOBS ))
  DATA_PIN=3-$(( JOBS - 1 ))
else
  DATA_CORES=$JOBS
  DATA_PIN=0-$(( JOBS - 1 ))
fi

log "2. $TRAIN_SCENES training kitchens x $EPISODES demos, $HELDOUT_SCENES held out ($DATA_CORES cores)"
generate "$TRAIN_SCENES" 0
eval "demos_extra=($DEMOS_ARGS)"
pin "$DATA_PIN" $PY -m factory stage=demos run_dir="$RUN" $COMMON \
  demos.episodes_per_scene="$EPISODES" demos.workers="$DATA_CORES" "${demos_extra[@]}"
pin "$DATA_PIN" $PY -m factory stage=dataset run_dir="$RUN" dataset.workers="$DATA_CORES"
generate "$HELDOUT_SCENES" 100000
echo "{\"data_seconds\": $(( $(date +%s) - t0 ))}" > "$OUT_DIR/data.json"
[ -z "$BENCH_PID" ] || wait "$BENCH_PID" || log "   the variants failed: $OUT_DIR/bench.log"

if [ "$STEPS" = 0 ]; then  # the measured steps/s (else 17: the compiled end-to-end recipe at
  # batch 512 on one H100; 11: the perception's on an H200) over the minutes left after ~2 of
  # compiling, less a tenth for the curve
  STEPS=$($PY - "$OUT_DIR/variants.json" "$TRAIN_MINUTES" "$BATCH" "$VISION" <<'EOF'
import json, sys
rate = 11.0 if sys.argv[4] == "perception" else 17.0
try:  # the benchmark's variants are end-to-end recipes
    if sys.argv[4] == "perception":
        raise ValueError
    rows = json.load(open(sys.argv[1]))["variants"]
    rate = next(r["train"]["steps_per_s"] for r in rows if "train" in r
                and r["train"]["compile"] and r["train"]["batch_size"] == int(sys.argv[3])
                and r["train"]["image_size"] == [84, 84])
except Exception:
    pass
print(int(rate * 0.9 * 60 * max(float(sys.argv[2]) - 2.0, 0.5)))
EOF
)
fi
POLICIES="$INPUTS"  # with SECOND_GPU: the second policy beside it on that GPU
if [ -n "$SECOND_GPU" ]; then POLICIES="$INPUTS $SECOND_NAME"; fi
log "3. $POLICIES: $STEPS steps, at most $TRAIN_MINUTES min, batch $BATCH"
$PY -m factory stage=eval run_dir="$RUN" $COMMON eval.policy=planner eval.episodes_per_scene="$EVAL_EPISODES" \
  eval.name=planner eval.workers=3 eval.batch=8 eval.videos=0 > "$OUT_DIR/planner.log" 2>&1 &
PLANNER=$!
n_pol=$(echo $POLICIES | wc -w)
# the curve: a held-out kitchen's episodes in one batch, one process each (each process a CUDA
# context: fewer contexts time-slice the training's GPU less; 2026-11-29, 2 x H200: 13.2 steps/s
# alone, 5-7 while 12 curve processes ran on the same GPU) and, on a two-GPU machine without
# SECOND_GPU, on GPU 1 (eval.device=cuda:1: factory/policy/learning_curve.py)
curve_workers=$HELDOUT_SCENES
curve_device=$DEVICE
if [ -z "$SECOND_GPU" ] && [ "$DEVICE" != cpu ] && [ "$(nvidia-smi -L 2>/dev/null | wc -l)" -gt 1 ]; then
  curve_device=cuda:1
fi
train_one() {  # train_one <name> <visible GPUs or empty>
  local gpu_env=() extra=() inputs=$1 vision=$VISION
  [ -z "$2" ] || gpu_env=(env CUDA_VISIBLE_DEVICES="$2")
  if [ "$1" != "$INPUTS" ]; then inputs=$SECOND_INPUTS vision=$SECOND_VISION; eval "extra=($SECOND_ARGS)"; fi
  "${gpu_env[@]}" $PY -m factory stage=train run_dir="$RUN" $COMMON train.name="$1" train.inputs="$inputs" \
    train.vision="$vision" train.video_cache=memory \
    train.steps="$STEPS" train.batch_size="$BATCH" train.max_minutes="$TRAIN_MINUTES" \
    train.device="$DEVICE" train.save_every=1000 train.log_every=100 \
    train.eval_every_minutes="$CURVE_MINUTES" train.eval_episodes="$CURVE_EPISODES" \
    eval.workers="$curve_workers" eval.batch="$CURVE_EPISODES" eval.device="$curve_device" "${extra[@]}"
}
evaluate_one() {  # evaluate_one <inputs> <visible GPUs or empty> <workers> <episodes> [overrides...]
  local gpu_env=()
  [ -z "$2" ] || gpu_env=(env CUDA_VISIBLE_DEVICES="$2")
  pin "${EVAL_CORES:-$CPU_PIN}" "${gpu_env[@]}" $PY -m factory stage=eval run_dir="$RUN" $COMMON eval.policy="$1" \
    eval.episodes_per_scene="$4" eval.device="$DEVICE" eval.videos=2 \
    eval.workers="$3" eval.batch=8 "${eval_extra[@]}" "${@:5}"
}
eval "eval_extra=($EVAL_ARGS)"
gpu_of() {  # the GPU a policy uses: empty (the default) without SECOND_GPU
  if [ -z "$SECOND_GPU" ]; then echo ""; elif [ "$1" = "$INPUTS" ]; then echo 0; else echo "$SECOND_GPU"; fi
}
WARM_PID=""
if [ -n "$EVAL_WARP" ] && [ -n "$WARP_WARM" ]; then  # the Warp kernels, beside the training
  warm_env=()
  [ "$curve_device" != cuda:1 ] || warm_env=(env CUDA_VISIBLE_DEVICES=1)
  warm_pin=0-$(( JOBS - 1 ))
  [ "$JOBS" -le 6 ] || warm_pin=$(( JOBS - 2 ))-$(( JOBS - 1 ))
  (
    first="$RUN/policy/$INPUTS/checkpoints/last/pretrained_model"
    waited=0  # the first checkpoint (train.save_every), or the training's end
    while [ ! -e "$first" ] && [ "$waited" -lt $(( ${TRAIN_MINUTES%.*} * 60 + 600 )) ]; do
      sleep 10; waited=$(( waited + 10 ))
    done
    t3=$(date +%s)
    pin "$warm_pin" "${warm_env[@]}" $PY -m factory stage=eval run_dir="$RUN" $COMMON \
      eval.policy="$INPUTS" eval.executor=warp eval.device=cpu eval.name=warp-warmup \
      eval.episodes_per_scene=1 eval.max_steps=2 eval.workers=1 eval.videos=0 \
      > "$OUT_DIR/eval-warp-warmup.log" 2>&1 \
      || log "   the Warp kernels' warm-up failed: $OUT_DIR/eval-warp-warmup.log"
    echo "{\"name\": \"warp-warmup\", \"seconds\": $(( $(date +%s) - t3 )), \"beside\": \"the training\"}" \
      > "$OUT_DIR/time-warp-warmup.json"
    log "   the held-out kitchens' Warp kernels compiled in $(( $(date +%s) - t3 )) s"
  ) &
  WARM_PID=$!
fi
t1=$(date +%s)
pids=()
for p in $POLICIES; do
  gpu=$(gpu_of "$p")
  if [ "$p" = "$INPUTS" ]; then train_one "$p" "$gpu" & else train_one "$p" "$gpu" > "$OUT_DIR/train-$p.log" 2>&1 & fi
  pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid" || log "   a training failed (pid $pid)"; done
log "   trained in $(( $(date +%s) - t1 )) s"
for p in $POLICIES; do
  cp "$RUN/policy/$p/train_log.jsonl" "$OUT_DIR/train_log-$p.jsonl" || true
  cp "$RUN/policy/$p/train.json" "$OUT_DIR/train-$p.json" || true
  if [ -n "$EXPORT_PARTS" ] && [ -e "$RUN/policy/$p/checkpoints/last/pretrained_model" ]; then
    last=$(readlink -f "$RUN/policy/$p/checkpoints/last")
    tar -chf - -C "$RUN/policy/$p" train.json "checkpoints/$(basename "$last")/pretrained_model" \
      | split -b "$EXPORT_PARTS" -d -a 2 - "$OUT_DIR/policy-$p.tar.part" \
      || log "   exporting $p failed"
  fi
done

log "4. final evaluation: $EVAL_EPISODES per held-out kitchen"
cpu_workers=$EVAL_WORKERS  # with EVAL_WARP, the cores the Warp evaluations' processes leave
[ -z "$EVAL_WARP" ] || cpu_workers=$(( EVAL_WORKERS - WARP_WORKERS - 2 > 0 ? EVAL_WORKERS - WARP_WORKERS - 2 : 1 ))
CPU_PIN=0-$(( JOBS - 1 ))  # with EVAL_WARP on a machine with cores to spare, the CPU env's
# evaluations keep off the Warp processes' cores (the first WARP_WORKERS x 2) and, on a
# two-GPU machine, run their policies on the other GPU: the Warp timing is not the CPU's
EVAL_GPU_OF_CPU=""
if [ -n "$EVAL_WARP" ] && [ "$JOBS" -gt $(( WARP_WORKERS * 2 + 4 )) ]; then
  CPU_PIN=$(( WARP_WORKERS * 2 ))-$(( JOBS - 1 ))
  cpu_workers=$(( JOBS - WARP_WORKERS * 2 - 2 ))  # a worker per core left, less the replay's 2
  if [ -z "$SECOND_GPU" ] && [ "$(nvidia-smi -L 2>/dev/null | wc -l)" -gt 1 ]; then EVAL_GPU_OF_CPU=1; fi
fi
log "   CPU env evaluations on cores $CPU_PIN${EVAL_GPU_OF_CPU:+, their policies on GPU $EVAL_GPU_OF_CPU}"
NEXT_CORE=${CPU_PIN%-*}
take_cores() {  # take_cores <n>: EVAL_CORES, the next n cores of CPU_PIN ("a-b"): each
  # evaluation its own, so that those running at once (each sizing its workers' threads from its
  # affinity, factory/cores.py) do not oversubscribe the machine; the whole range once used up
  local hi=${CPU_PIN#*-} a=$NEXT_CORE
  if [ $(( a + $1 - 1 )) -gt "$hi" ]; then EVAL_CORES=$CPU_PIN; return; fi
  NEXT_CORE=$(( a + $1 ))
  EVAL_CORES="$a-$(( a + $1 - 1 ))"
}
pids=()
ks_list=()
for k in $ENSEMBLE_KS; do ks_list+=("$k"); done
n_eval=$(( n_pol + ${#ks_list[@]} ))
share=$(( cpu_workers / n_eval > 0 ? cpu_workers / n_eval : 1 ))
for p in $POLICIES; do
  gpu=$(gpu_of "$p")
  [ -z "$EVAL_GPU_OF_CPU" ] || gpu=$EVAL_GPU_OF_CPU
  workers=$share
  # the default evaluation has the most episodes: its share of the workers by its episodes
  [ ${#ks_list[@]} = 0 ] || workers=$(( cpu_workers * EVAL_EPISODES / (EVAL_EPISODES * n_pol + KS_EPISODES * ${#ks_list[@]}) ))
  [ "$workers" -gt 0 ] || workers=1
  take_cores "$workers"
  evaluate_one "$p" "$gpu" "$workers" "$EVAL_EPISODES" &
  pids+=($!)
done
for k in "${ks_list[@]}"; do  # the same policy and configurations with other ensembling
  name="$INPUTS-k$k"
  [ "$k" != -1 ] || name="$INPUTS-plain"
  gpu=$(gpu_of "$INPUTS")
  [ -z "$EVAL_GPU_OF_CPU" ] || gpu=$EVAL_GPU_OF_CPU
  workers=$(( cpu_workers * KS_EPISODES / (EVAL_EPISODES * n_pol + KS_EPISODES * ${#ks_list[@]}) ))
  [ "$workers" -gt 0 ] || workers=1
  take_cores "$workers"
  evaluate_one "$INPUTS" "$gpu" "$workers" "$KS_EPISODES" eval.ensemble="$k" eval.name="$name" \
    > "$OUT_DIR/eval-$name.log" 2>&1 &
  pids+=($!)
done
if [ -n "$EVAL_WARP" ]; then  # the GPU's evaluations, beside the CPU's (header)
  REPLAY_LIST=$($PY - "$RUN" "$REPLAY_SCENES" <<'EOF3'
import json, sys
from pathlib import Path
scenes = json.loads((Path(sys.argv[1]) / "dataset/merged/meta/factory.json").read_text())["scenes"]
print("[" + ",".join(sorted(scenes)[: int(sys.argv[2])]) + "]")
EOF3
)
  # the same replays on the CPU env, on two cores
  take_cores 2
  pin "$EVAL_CORES" $PY -m factory stage=eval run_dir="$RUN" $COMMON eval.policy=replay eval.name=replay-cpu \
    "eval.scenes=$REPLAY_LIST" eval.workers=2 eval.batch=8 eval.videos=0 \
    > "$OUT_DIR/eval-replay-cpu.log" 2>&1 &
  pids+=($!)
  warp_one() {  # warp_one <policy> <name> <more overrides...>: timed, on MuJoCo Warp
    # (EXECUTOR=warp_opengl: Warp's physics with OpenGL's cameras)
    local t2
    t2=$(date +%s)
    $PY -m factory stage=eval run_dir="$RUN" $COMMON eval.policy="$1" eval.executor="${EXECUTOR:-warp}" \
      eval.name="$2" eval.device="$DEVICE" eval.videos=0 "${@:3}" > "$OUT_DIR/eval-$2.log" 2>&1 \
      || log "   $2 on warp failed: $OUT_DIR/eval-$2.log"
    echo "{\"policy\": \"$1\", \"name\": \"$2\", \"seconds\": $(( $(date +%s) - t2 )), \
\"beside\": \"the CPU evaluations\"}" > "$OUT_DIR/time-$2.json"
    log "   $2 on MuJoCo Warp in $(( $(date +%s) - t2 )) s"
  }
  [ -z "$WARM_PID" ] || wait "$WARM_PID" || true
  log "4a. MuJoCo Warp: $INPUTS on $EVAL_EPISODES per held-out kitchen, then replay of $REPLAY_LIST"
  warp_one "$INPUTS" "$INPUTS-warp" eval.episodes_per_scene="$EVAL_EPISODES" \
    eval.workers="$WARP_WORKERS" "${eval_extra[@]}"
  if [ -n "$SECOND_GPU" ]; then  # the second policy on the same configurations (A/B on both envs)
    warp_one "$SECOND_NAME" "$SECOND_NAME-warp" eval.episodes_per_scene="$EVAL_EPISODES" \
      eval.workers="$WARP_WORKERS" "${eval_extra[@]}"
  fi
  warp_one replay replay-warp "eval.scenes=$REPLAY_LIST" eval.workers=1
  [ -z "$WARP_OPENGL" ] || EXECUTOR=warp_opengl warp_one "$INPUTS" "$INPUTS-warp-opengl" \
    eval.episodes_per_scene="$WARP_OPENGL" eval.workers="$WARP_WORKERS" "${eval_extra[@]}"
  [ -z "$WARP_PLANNER" ] || warp_one planner planner-warp eval.episodes_per_scene="$EVAL_EPISODES" \
    eval.workers="$WARP_WORKERS"
fi
touch "$OUT_DIR/gpu_free"  # the trainings and the GPU's evaluations are over
for pid in "${pids[@]}"; do wait "$pid" || log "   an evaluation failed (pid $pid)"; done
log "   evaluated in $(( $(date +%s) - t1 )) s"
wait "$PLANNER" || log "   the planner evaluation failed: $OUT_DIR/planner.log"
if [ "$VISION" = perception ] && [ -n "$PERCEPTION_CHECK" ]; then
  # the perception's position errors on the training frames and on demos recorded afterwards
  # in the held-out kitchens (their own run directory: never in the training data)
  HELD=$RUN-heldout-frames
  rm -rf "$HELD"; mkdir -p "$HELD/scenes"
  $PY - "$RUN" "$HELD" <<'EOF2'
import json, shutil, sys
from pathlib import Path
run, held = Path(sys.argv[1]), Path(sys.argv[2])
seen = set(json.loads((run / "dataset/merged/meta/factory.json").read_text())["scenes"])
for d in sorted((run / "scenes").iterdir()):
    if d.is_dir() and d.name not in seen and (d / "scene.json").is_file():
        shutil.copytree(d, held / "scenes" / d.name)
EOF2
  [ -d "$RUN/assets" ] && ln -sfn "$RUN/assets" "$HELD/assets"
  $PY -m factory stage=demos run_dir="$HELD" $COMMON demos.episodes_per_scene="$PERCEPTION_CHECK" \
    demos.workers="$JOBS" seed=777 > "$OUT_DIR/heldout-frames.log" 2>&1 \
    && $PY -m factory stage=dataset run_dir="$HELD" >> "$OUT_DIR/heldout-frames.log" 2>&1 \
    && $PY scripts/perception_error.py --policy "$RUN/policy/$INPUTS" --dataset "$HELD/dataset/merged" \
      --out "$OUT_DIR/perception-error-heldout.json" >> "$OUT_DIR/heldout-frames.log" 2>&1 \
    || log "   the held-out perception check failed: $OUT_DIR/heldout-frames.log"
  $PY scripts/perception_error.py --policy "$RUN/policy/$INPUTS" --dataset "$RUN/dataset/merged" \
    --out "$OUT_DIR/perception-error-train.json" >> "$OUT_DIR/heldout-frames.log" 2>&1 || true
  log "   perception errors: $OUT_DIR/perception-error-*.json"
fi
for d in "$RUN"/eval/*/; do
  [ -f "$d/results.json" ] && cp "$d/results.json" "$OUT_DIR/eval-$(basename "$d").json"
done
log "done in $(( $(date +%s) - t0 )) s"
