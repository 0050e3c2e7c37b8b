#!/usr/bin/env bash
# `make demo`: the main job on the embedded default, each subsystem's part in data-flow order.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p outputs
for part in pipelines catalog scenes sim socialnav train retrieval; do
  script="scripts/demo_${part}.sh"
  if [ -f "$script" ]; then
    echo "== demo: $part"
    bash "$script"
  fi
done
echo "== demo done: see outputs/"
