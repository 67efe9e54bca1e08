#!/usr/bin/env bash
# Builds the bundled Panda artifacts (sik_ros/bundles/panda/) from the trained runs of
# scripts/train_bundled.sh: encodes the 30-degree dataset with each model, keeps the distinct
# posture indices per 5 cm cell, and writes model + table + bundle.json (and, for the pose
# model, the seed table of the family search's starts: 30,000 rows of the dataset).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
OUT=${OUT:-sik_ros/bundles/panda}
RUNS=${RUNS:-runs}  # the runs' folder: <RUNS>/sik_<goal>/last.pt
for goal in position pose; do
  run=$RUNS/sik_$goal
  [ -f "$run/model.pt" ] || $PY -c "
from sik_ros.learning.checkpoints import export_model, load_checkpoint
export_model(load_checkpoint('$run/last.pt'), '$run/model.pt')"
  # both tables keep each index's orientation (pose goals choose indices by it); the position
  # table also keeps its decoded posture at the cell centre (sik-index's default for position
  # models) and marks the indices whose decoded tip lands within 1.5 cm of the goal at and one
  # cell around their cell (the look-up by position gives those); the pose table keeps 12
  # indices per cell
  opts=(--max-tip-error 0.015)
  [ "$goal" = pose ] && opts=(--max-per-cell 12)
  $PY -m sik_ros.cli.index --model "$run/model.pt" --dataset "$DATA" \
    --out "$run/table.npz" --force --bundle "$OUT" "${opts[@]}"
done
du -ch "$OUT"/* | tail -1
