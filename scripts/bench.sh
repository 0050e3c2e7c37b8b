#!/usr/bin/env bash
# `make bench`: every script in benchmarks/ once, with its quick options (minutes, not the published figures).
# Figures are printed (and kept in $OUT/<name>.txt), never asserted. The full runs, their targets and the figures
# quoted in README.md: each script's docstring and benchmarks/results/.
set -euo pipefail
cd "$(dirname "$0")/.."
export HF_HUB_OFFLINE=1 TRANSFORMERS_OFFLINE=1 MPLBACKEND=Agg
OUT=${OUT:-outputs/bench}
mkdir -p "$OUT"

bench() {  # bench NAME SCRIPT ARGS...: run one benchmark, print and keep its output
  local name=$1
  shift
  echo "== bench: $name (python $*)"
  python "$@" 2>&1 | tee "$OUT/$name.txt"
}

bench sim_steps benchmarks/sim_steps.py --quick                                  # = curbside sim bench --quick
bench scenes benchmarks/scenes.py --count 10
bench agents benchmarks/agents.py --quick
bench world_memory benchmarks/world_memory.py --builds 100 --envs 10 --specs 10
bench catalog_query benchmarks/catalog_query.py --sizes 10000 --repeats 10
bench pool benchmarks/pool.py --n 2000
bench asset_retrieval benchmarks/asset_retrieval.py 3
# The plumbing of the Table 1 harness (every baseline, tiny budget), written under $OUT, not benchmarks/results/.
bench table1_smoke benchmarks/table1.py --budget smoke --tasks PointNav --out "$OUT/table1_smoke" --fresh
echo "== bench done: outputs in $OUT/"
