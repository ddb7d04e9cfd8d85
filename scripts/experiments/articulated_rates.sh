#!/usr/bin/env bash
# Issue 35's rate check on one GPU machine, after scripts/gpu_install.sh: the fixed task and the
# articulated tasks through `scripts/bench_demos.py --executor warp`, one after the other on the
# same kitchens, cores and GPU, so that their demos per hour compare side by side (the issue's
# "within 20 % of the fixed task's rate").
#
#   TASKS (default "pick_place open close place_inside"): each gets its own copy of BENCH_RUN's
#     scenes and assets (default runs/bench_art4: 4 kitchens generated with articulated
#     furniture, as `bench_demos.py --task open` generates them), SCENES x EPISODES episodes;
#   CORES (default 12): bench_demos.py pins itself to cores 0..CORES-1, planning processes
#     CORES - 1; the rest of the machine may run something else (a camera policy's training);
#   GPU (default: every GPU visible): CUDA_VISIBLE_DEVICES of the benches;
#   CACHE (default /tmp/warpcache-art, emptied first): one kernel cache for all the tasks, so
#     the first task's figure includes the bare machine's compilation and the next ones find the
#     kernels they share built;
#   START_AFTER: files to wait for before starting (e.g. another script's data being made).
#
# Use (repository root, in the background): bash scripts/experiments/articulated_rates.sh DIR
# DIR gets demos-<task>.json and bench-<task>.log per task, steps.log; the episodes are deleted
# after each task (its JSON kept).
set -u
DIR=${1:?a folder for the results}
TASKS=${TASKS:-pick_place open close place_inside}
BENCH_RUN=${BENCH_RUN:-runs/bench_art4}
SCENES=${SCENES:-4}
EPISODES=${EPISODES:-384}
CORES=${CORES:-12}
CACHE=${CACHE:-/tmp/warpcache-art}
START_AFTER=${START_AFTER:-}
PY=${PY:-python3}
mkdir -p "$DIR"
stamp() { echo "$(date -u +%H:%M:%S) $*" | tee -a "$DIR/steps.log"; }
for f in $START_AFTER; do
  while [ ! -e "$f" ]; do sleep 5; done
done
[ -z "${GPU:-}" ] || export CUDA_VISIBLE_DEVICES=$GPU
rm -rf "$CACHE"
stamp "articulated rates: $TASKS; $SCENES x $EPISODES on $CORES cores; GPU ${GPU:-all}"
for task in $TASKS; do
  run=$DIR/run-$task
  rm -rf "$run"; mkdir -p "$run"
  cp -r "$BENCH_RUN/scenes" "$run/"
  [ -d "$BENCH_RUN/assets" ] && cp -r "$BENCH_RUN/assets" "$run/"
  stamp "$task: start"
  $PY scripts/bench_demos.py --task "$task" --executor warp --scenes "$SCENES" \
    --episodes "$EPISODES" --cores "$CORES" --kernel-cache "$CACHE" --run-dir "$run" \
    --out "$DIR/demos-$task.json" > "$DIR/bench-$task.log" 2>&1
  stamp "$task: rc=$? $(grep -E 'successful demos' "$DIR/bench-$task.log" | tail -1)"
  rm -rf "$run/episodes"
done
stamp "articulated rates: done"
