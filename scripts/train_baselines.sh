#!/usr/bin/env bash
# Trains the paper's comparison models on the 30-degree dataset, one after the other, each within
# a wall-time budget (seconds): PSIK, the FCN on the original and on the uni-position dataset, and
# ANFIS (particle swarm). Resumable like train_bundled.sh. Output: runs/baselines/<name>.pt
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
BUDGET=${BUDGET:-600}
mkdir -p runs/baselines
train() {  # name, steps, then sik-train arguments
  local name=$1 steps=$2; shift 2
  local resume=()
  [ -f "runs/$name/last.pt" ] && resume=(--resume)
  $PY -m sik_ros.cli.train --dataset "$DATA" --out "runs/$name" --steps "$steps" \
    --max-time "$BUDGET" --threads 1 --quiet --export "runs/baselines/${name#base_}.pt" \
    "${resume[@]}" "$@"
}
train base_anfis 200 --model anfis --goal position --uni-position --eval-every 20
train base_fcn 1500 --model fcn --goal position
train base_fcn_uni 1500 --model fcn --goal position --uni-position
train base_psik 2000 --model psik --goal position --latent-dim 4 --fk-weight 0
