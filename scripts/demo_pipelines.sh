#!/usr/bin/env bash
# Distribution extraction demo: `dvc repro` (offline, Helsinki -> FI), the pool's top clusters, the plot.
set -euo pipefail
cd "$(dirname "$0")/.."
export DVC_NO_ANALYTICS=1 HF_HUB_OFFLINE=1 TRANSFORMERS_OFFLINE=1 MPLBACKEND=Agg
PATH="$(pwd)/.venv/bin:$PATH"
dvc repro --all-pipelines   # the distribution half (dvc.yaml) and the asset half (retrieval/dvc.yaml)
dvc metrics show
curbside pool show --top 10
mkdir -p outputs
cp data/distribution/distribution.png outputs/pipelines_distribution.png
echo "wrote outputs/pipelines_distribution.png"
