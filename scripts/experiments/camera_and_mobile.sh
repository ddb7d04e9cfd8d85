#!/usr/bin/env bash
# Issue 33's two camera policies in one GPU session on one machine (16 cores, one GPU), each
# script's steps where the other leaves the cores or the GPU free:
#
#   camera_policy.sh (the paper's setting, fixed base; RUN=$ROOT/camera): its data on every
#     core; its RGB-D training; then, with EVAL_WARP (default 1), replays and the policy on
#     MuJoCo Warp while the GPU is otherwise idle; then its CPU evaluations;
#   mobile_camera_policy.sh (RUN=$ROOT/mobile): its data on MOBILE_JOBS cores once the first
#     script's data is made (START_AFTER), beside that training; its training once the first
#     script no longer needs the GPU (TRAIN_AFTER); its evaluation on the CPU env.
#
# Settings pass through to each script (their headers list them): CAMERA_ENV and MOBILE_ENV are
# extra VAR=value words for each. The defaults below are the sizes of one session (about 40
# minutes on a bare H200). A tiny dry run on a CPU:
#   ROOT=/tmp/cm CAMERA_ENV="TRAIN_SCENES=1 HELDOUT_SCENES=1 EPISODES=2 TRAIN_MINUTES=0.2 STEPS=4
#     BATCH=2 EVAL_EPISODES=1 CURVE_MINUTES=0.05 CURVE_EPISODES=1 DEVICE=cpu REPLAY_SCENES=1"
#     MOBILE_ENV="SCENES=1 EPISODES=2 SIZE=32 TRAIN_MINUTES=0.2 STEPS=4 BATCH=2 EVAL_EPISODES=1
#     CURVE_MINUTES=0 EVAL_MAX_STEPS=120 DEVICE=cpu" bash scripts/experiments/camera_and_mobile.sh
# Results: $ROOT/camera/results and $ROOT/mobile/results; logs $ROOT/camera.log, $ROOT/mobile.log.
set -euo pipefail
cd "$(dirname "$0")/../.."

ROOT=${ROOT:-runs/cameras}
JOBS=${JOBS:-$(getconf _NPROCESSORS_ONLN)}
MOBILE_JOBS=${MOBILE_JOBS:-$(( JOBS / 2 > 0 ? JOBS / 2 : 1 ))}  # the mobile data's cores
CAMERA_ENV=${CAMERA_ENV:-}
MOBILE_ENV=${MOBILE_ENV:-}
mkdir -p "$ROOT"
echo "$(date +%T) cameras: camera_policy.sh in $ROOT/camera, mobile_camera_policy.sh in $ROOT/mobile"
# shellcheck disable=SC2086  # the *_ENV words are VAR=value pairs
env EPISODES=30 STEPS=6500 TRAIN_MINUTES=12 EVAL_EPISODES=90 EVAL_WARP=1 \
  EVAL_WORKERS=$(( JOBS / 2 > 0 ? JOBS / 2 : 1 )) $CAMERA_ENV RUN="$ROOT/camera" \
  bash scripts/experiments/camera_policy.sh > "$ROOT/camera.log" 2>&1 &
CAMERA=$!
# shellcheck disable=SC2086
env SCENES=8 EPISODES=25 TRAIN_MINUTES=9 EXECUTOR=cpu JOBS="$MOBILE_JOBS" \
  EVAL_WORKERS=$(( JOBS * 3 / 4 > 0 ? JOBS * 3 / 4 : 1 )) $MOBILE_ENV RUN="$ROOT/mobile" \
  START_AFTER="$ROOT/camera/results/data.json $ROOT/camera/results/gpu_free" TRAIN_AFTER="$ROOT/camera/results/gpu_free" \
  bash scripts/experiments/mobile_camera_policy.sh > "$ROOT/mobile.log" 2>&1 &
MOBILE=$!
rc=0
wait "$CAMERA" || { rc=$?; echo "camera_policy.sh failed ($rc): $ROOT/camera.log"; }
wait "$MOBILE" || { rc=$?; echo "mobile_camera_policy.sh failed ($rc): $ROOT/mobile.log"; }
echo "$(date +%T) cameras: done"
exit "$rc"
