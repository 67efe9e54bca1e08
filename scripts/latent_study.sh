#!/usr/bin/env bash
# The paper's latent-size study (index sizes 1 to 7), on a short budget: one SIK position model
# per size, same data, seed, layers and schedule, two at a time. Output: runs/latent/latent_<d>.pt
# for `sik-eval --latent-study runs/latent`.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DATA=${DATA:-data/panda30}
STEPS=${STEPS:-700}
BUDGET=${BUDGET:-170}
mkdir -p runs/latent
one() {
  $PY -m sik_ros.cli.train --dataset "$DATA" --out "runs/latent/run_$1" --model sik \
    --goal position --latent-dim "$1" --steps "$STEPS" --max-time "$BUDGET" --fk-weight 0 \
    --eval-every 350 --threads 1 --quiet --export "runs/latent/latent_$1.pt"
}
(one 1; one 3; one 5; one 7) &
(one 2; one 4; one 6) &
wait
