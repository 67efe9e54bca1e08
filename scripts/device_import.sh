#!/usr/bin/env bash
# Brings the device recipe's checkpoints (scripts/device_train.py --out, the files the device
# tool brought back) into a bundle here: each sik_<goal>.pt becomes $RUNS/sik_<goal>/last.pt,
# then build_bundle.sh builds the tables over the 30-degree dataset and the bundle $OUT (not
# the shipped one unless OUT says so). The baselines there (psik.pt, fcn.pt, fcn_uni.pt,
# anfis.pt) are sik-eval's --baselines folder as they are.
#   scripts/device_import.sh DIR        (RUNS=runs/device OUT=runs/device/bundle DATA=data/panda30)
set -euo pipefail
cd "$(dirname "$0")/.."
DIR=${1:?usage: scripts/device_import.sh DIR (the checkpoints brought back)}
export RUNS=${RUNS:-runs/device} OUT=${OUT:-runs/device/bundle}
for goal in position pose; do
  if [ -f "$DIR/sik_$goal.pt" ]; then
    mkdir -p "$RUNS/sik_$goal"
    cp "$DIR/sik_$goal.pt" "$RUNS/sik_$goal/last.pt"
    rm -f "$RUNS/sik_$goal/model.pt"
  fi
done
bash scripts/build_bundle.sh
