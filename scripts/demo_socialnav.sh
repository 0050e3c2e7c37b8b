#!/usr/bin/env bash
# SocialNav demo: one expert episode among pedestrians, vulnerable road users, robots and traffic;
# writes outputs/socialnav.json (metrics), outputs/socialnav.gif (top-down map, agents by kind with trails)
# and outputs/socialnav.png (a middle frame), then evaluates the expert over a few episodes.
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-python}"
export HF_HUB_OFFLINE=1 MPLBACKEND=Agg
mkdir -p outputs
"$PY" -m sim.agents.demo --out outputs/socialnav --seed 0 --agents 24
curbside sim eval --task SocialNav --episodes 3 --json > outputs/socialnav_eval.json
cat outputs/socialnav_eval.json
