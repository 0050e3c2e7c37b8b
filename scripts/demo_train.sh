#!/usr/bin/env bash
# Training demo: expert demonstrations (Minari), a short PPO run and BC on PointNav, each evaluated on the test
# split. Minutes, not the benchmark: `python benchmarks/table1.py --budget small` trains every baseline (~1 h).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-outputs/train}
mkdir -p "$OUT"
resume() { [ -f "$1/run.json" ] && echo --resume || true; }  # a second demo goes on from the first one's runs
curbside demos collect --task PointNav --steps 3000 --out "$OUT/demos"
curbside train run --algo ppo --task PointNav --steps 30000 --envs 4 --scenes 16 --out "$OUT/ppo" $(resume "$OUT/ppo")
curbside train eval "$OUT/ppo" --split test --episodes 10 --json > "$OUT/ppo_test.json"
curbside train run --algo bc --task PointNav --steps 3000 --demos "$OUT/demos/curbside/pointnav-expert-v0" --out "$OUT/bc" $(resume "$OUT/bc")
curbside train eval "$OUT/bc" --split test --episodes 10 --json > "$OUT/bc_test.json"
for algo in ppo bc; do
  echo "$algo (test split): $(python -c "import json,sys; d=json.load(open('$OUT/${algo}_test.json')); print(f\"SR {d['sr']:.2f} SPL {d['spl']:.2f} Cost {d['cost']:.2f}\")")"
done
