#!/bin/bash
# Demos as an N-task array (each task records its shard and exports it to LeRobot), then the
# merged LeRobot dataset once every task succeeded.
#
#   bash scripts/slurm/pipeline.sh runs/big 8 [overrides...]
set -euo pipefail
RUN_DIR=${1:?usage: pipeline.sh RUN_DIR TASKS [overrides...]}
TASKS=${2:?usage: pipeline.sh RUN_DIR TASKS [overrides...]}
shift 2
HERE=$(cd "$(dirname "$0")" && pwd)
ARRAY=$(sbatch --parsable --array=0-$((TASKS - 1)) "$HERE/stage_array.sbatch" all "$RUN_DIR" \
  "all.stages=[demos,dataset]" "$@")
echo "demos + shard export: array job $ARRAY ($TASKS tasks)"
MERGE=$(sbatch --parsable --dependency=afterok:"$ARRAY" "$HERE/single.sbatch" dataset "$RUN_DIR")
echo "dataset merge: job $MERGE (after $ARRAY)"
