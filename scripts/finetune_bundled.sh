#!/usr/bin/env bash
# Fine-tunes the bundled Panda models from their weights with recipe B of docs/training.md
# (docs/training.md, "Recipes"): batches drawn afresh every step (uniform joint angles, torch
# FK), the FK term at FK_WEIGHT (CYCLE_WEIGHT > 0 adds the cycle term; the ablation found it not
# worth its cost from these warm starts),
# bfloat16 autocast, batch 8192. Resumable: run it again and each run continues from
# $RUNS/<name>/last.pt (keep RUNS outside the work tree so that a clean checkout keeps the runs).
# GOALS="position pose" trains both (in parallel, one thread each); THREADS per run.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
RUNS=${RUNS:-runs}
GOALS=${GOALS:-position}
THREADS=${THREADS:-2}
MAX_TIME=${MAX_TIME:-5000}
STEPS=${STEPS:-12000}
FK_WEIGHT=${FK_WEIGHT:-0.05}
CYCLE_WEIGHT=${CYCLE_WEIGHT:-0}
LR=${LR:-3e-4}
[ -d "$DATA" ] || $PY -m sik_ros.cli.collect --robot panda --interval 30 --out "$DATA"
for goal in $GOALS; do
  name=finetune_$goal
  if [ -f "$RUNS/$name/last.pt" ]; then
    args=(--resume)
  else
    args=(--init "sik_ros/bundles/panda/sik_$goal.pt" --goal "$goal" --sampler uniform
          --fk-weight "$FK_WEIGHT" --cycle-weight "$CYCLE_WEIGHT" --lr "$LR" --steps "$STEPS"
          --batch-size 8192 --bf16 --threads "$THREADS" --eval-every 250 --checkpoint-every 250)
    [ "$goal" = pose ] && args+=(--latent-dim 1 --rot-weight 4)
  fi
  $PY -m sik_ros.cli.train --dataset "$DATA" --out "$RUNS/$name" --max-time "$MAX_TIME" \
    --quiet --export "$RUNS/$name/model.pt" "${args[@]}" &
done
wait
