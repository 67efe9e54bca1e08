#!/usr/bin/env bash
# Trains the bundled Panda models (SIK position and SIK pose) exactly as recorded in
# docs/training.md. Resumable: run it again after an interruption and each run continues from
# runs/<name>/last.pt. Needs the 30-degree dataset: sik-collect --out data/panda30
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
MAX_TIME=${MAX_TIME:-3900}
# the paper's joint loss first; the FK consistency term joins at FK_START (see docs/training.md)
FK_WEIGHT=${FK_WEIGHT:-0.005}
POS_STEPS=${POS_STEPS:-14000}
POSE_STEPS=${POSE_STEPS:-12000}
[ -d "$DATA" ] || $PY -m sik_ros.cli.collect --robot panda --interval 30 --out "$DATA"
train() {  # name, then sik-train arguments
  local name=$1; shift
  local resume=()
  [ -f "runs/$name/last.pt" ] && resume=(--resume)
  $PY -m sik_ros.cli.train --dataset "$DATA" --out "runs/$name" \
    --fk-weight "$FK_WEIGHT" --max-time "$MAX_TIME" --threads 1 --quiet --export "runs/$name/model.pt" \
    "${resume[@]}" "$@"
}
train sik_position --model sik --goal position --latent-dim 4 --steps "$POS_STEPS" --fk-start 8000 &
train sik_pose --model sik --goal pose --latent-dim 1 --steps "$POSE_STEPS" --fk-start 7000 &
wait
# pose, second part (docs/training.md): the schedule extended to POSE_STEPS2 with a stronger FK
# term, its orientation part weighted 4x
POSE_STEPS2=${POSE_STEPS2:-28000}
FK_WEIGHT=0.01 train sik_pose --steps "$POSE_STEPS2" --rot-weight 4
