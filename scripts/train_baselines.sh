#!/usr/bin/env bash
# Trains the paper's comparison models on the 30-degree dataset, one after the other, each within
# a wall-time budget (seconds; a run stopped by it resumes where it stopped when the script is run
# again): ANFIS (particle swarm), the FCN on the original and on the uni-position dataset, and
# PSIK by the recipe of the bundled SIK models (started from the bundled SIK position model, the
# FK term, fresh uniform samples, the KL weight annealed). Output: runs/baselines/<name>.pt and
# runs/psik/last.pt; scripts/ship_baselines.py then ships them (docs/training.md, "Baselines").
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
BUDGET=${BUDGET:-600}            # each of ANFIS and the two FCNs
PSIK_BUDGET=${PSIK_BUDGET:-2400}
ONLY=${ONLY:-anfis fcn fcn_uni psik}
mkdir -p runs/baselines
train() {  # name, budget, steps, then sik-train arguments
  local name=$1 budget=$2 steps=$3; shift 3
  case " $ONLY " in *" ${name#base_} "*) ;; *) return 0 ;; esac
  local resume=()
  [ -f "runs/$name/last.pt" ] && resume=(--resume)
  $PY -m sik_ros.cli.train --dataset "$DATA" --out "runs/$name" --steps "$steps" \
    --max-time "$budget" --threads 1 --quiet --export "runs/baselines/${name#base_}.pt" \
    "${resume[@]}" "$@"
}
train base_anfis "$BUDGET" 1000 --model anfis --goal position --uni-position --eval-every 50
train base_fcn "$BUDGET" 5000 --model fcn --goal position --batch-size 8192 --bf16 --lr 5e-4 \
  --eval-every 250
train base_fcn_uni "$BUDGET" 5000 --model fcn --goal position --uni-position --batch-size 8192 \
  --bf16 --lr 5e-4 --eval-every 250
# --init only starts a run (a resumed one has its weights)
init=(--init sik_ros/bundles/panda/sik_position.pt)
[ -f runs/psik/last.pt ] && init=()
train psik "$PSIK_BUDGET" 6000 --model psik --goal position "${init[@]}" --fk-weight 0.05 \
  --kl-weight 0.001 --kl-anneal 1000 --sampler uniform --lr 3e-4 --batch-size 8192 --bf16 \
  --eval-every 250 --checkpoint-every 250
