#!/usr/bin/env bash
# Simulator demo: expert PointNav episodes for every wheeled machine -> metrics JSON, plus a GIF per machine.
set -euo pipefail
OUT=${OUT:-outputs/sim}
EPISODES=${EPISODES:-5}
mkdir -p "$OUT"
export HF_HUB_OFFLINE=1
for machine in delivery_bot delivery_bot_mod1 delivery_bot_mod2 wheelchair mobility_scooter; do
  curbside sim eval --task PointNav --policy expert --episodes "$EPISODES" --machine "$machine" --json \
    > "$OUT/pointnav_${machine}.json"
  echo "$machine: $(head -c 300 "$OUT/pointnav_${machine}.json")..."
  curbside sim rollout --policy expert --machine "$machine" --seed 1 --out "$OUT/pointnav_${machine}.gif" \
    --metrics-out "$OUT/pointnav_${machine}_rollout.json"
done
curbside sim bench --quick --json > "$OUT/bench_quick.json"
cat "$OUT/bench_quick.json"
