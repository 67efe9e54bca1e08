#!/usr/bin/env bash
# Every benchmark behind docs/benchmarks.md and the README's table, then the tables rendered.
#
#   bash bench/run_all.sh                 # everything (about an hour on 2 busy cores, plus
#                                         # the UR5's 30-minute sik-build the first time)
#   ONLY="solve paths" bash bench/run_all.sh   # some of them
#
# Each benchmark writes docs/results/<name>.json (figures, command, date, commit, machine) and
# its printed output to docs/results/<name>.txt; bench/render.py then rewrites the tables.
# Run it from the repository's root in the set-up venv (make bench does both). Commit first:
# figures measured on uncommitted code are marked as such in the tables.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
PY=${PY:-python}
OUT=docs/results
mkdir -p "$OUT"
export OMP_NUM_THREADS=1

run() {  # run NAME ARGS...: python bench/<script> ARGS, printed output kept in $OUT/NAME.txt
  local name=$1; shift
  if [[ -n "${ONLY:-}" && " $ONLY " != *" ${name%%-*} "* && " $ONLY " != *" $name "* ]]; then
    return 0
  fi
  echo "== $name: $*" >&2
  "$PY" "$@" --json "$OUT/$name.json" | tee "$OUT/$name.txt" || echo "!! $name failed" >&2
}

# In order of what the README's table needs; sizes a shared 2-core machine runs in about an
# hour (the full sizes of the scripts' docstrings take several times longer).
run solve bench/solve.py --targets 100
run paths bench/paths.py --paths 100
run tracik_protocol bench/tracik_protocol.py --targets 10000
run service bench/service.py --requests 1000 --duration 10 --goals mixed
run stream bench/stream.py --rates 100 500 1000 --duration 10
run stream-busy bench/stream.py --rates 100 500 1000 --duration 10 --busy
run executors bench/executors.py --duration 5
run first_answer bench/first_answer.py --arms panda,ur5,xarm7,kinova,so100,z1,ur10,baxter,tree --targets 50 --learning-time 90 --learning-rows 200000
run moveit_ik bench/moveit_ik.py --requests 2000
run batch_service bench/batch_service.py --targets 200 --repeats 5
# OLD: a revision to compare the node's round trip with (e.g. OLD=013d4cc, 0.4.0)
[[ -n "${OLD:-}" ]] && run service_ab bench/service_ab.py "old=@$OLD" new=. --requests 300
run arms bench/arms.py --arms panda,ur5 --targets 50 --max-attempts 100
run families bench/families.py --panda-poses 40 --near-singular 8 --seeds 20,21,22 --arm-bundle bundles_bench/ur5 --arm-poses 20 --arm-seeds 20,21,22
run solve_ab-panda-pose bench/solve_ab.py a=. b=. --goal pose --targets 100
run solve_ab-panda-analytic bench/solve_ab.py ours=. frankik=frankik tracik=tracik --goal pose \
  --num 1 --targets 200
run paths_ab bench/paths_ab.py a=. b=. --paths 40
run service-position bench/service.py --requests 1000 --duration 10
run soak bench/soak.py --requests 3000 --clients 16
run service_probe bench/service_probe.py --requests 200
run sweep bench/sweep.py --arms z1,so101 --targets 20 --attempts 100
run collect bench/collect.py --runs 3
run train_step bench/train_step.py --batches 2048 --threads 1,2 --steps 5 --repeats 2
run solve_ab-ur5-pose-busy bench/solve_ab.py a=. b=. --goal pose --targets 100 \
  --bundle bundles_bench/ur5 --busy 90
run solve_ab-panda-position bench/solve_ab.py a=. b=. --goal position --targets 100
run service-processes2 bench/service.py --requests 1000 --duration 10 --goals mixed \
  -p solver_processes:=2
"$PY" bench/render.py
