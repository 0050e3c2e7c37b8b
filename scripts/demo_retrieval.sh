#!/usr/bin/env bash
# Retrieval demo: ingest a small local folder and the procedural source, evaluate, copy a contact sheet to outputs/.
set -euo pipefail
export HF_HUB_OFFLINE=1
OUT=outputs/retrieval_demo
mkdir -p "$OUT/meshes"
python - <<'PY'
import trimesh
m = trimesh.creation.cone(radius=0.15, height=0.7, sections=24); m.visual.face_colors = [240, 110, 20, 255]
m.export("outputs/retrieval_demo/meshes/traffic_cone.ply")
b = trimesh.creation.cylinder(radius=0.25, height=0.9); b.apply_translation([0, 0, 0.45]); b.visual.face_colors = [60, 60, 60, 255]
b.export("outputs/retrieval_demo/meshes/trash_bin.ply")
PY
curbside catalog ingest --source "local:$OUT/meshes" --catalog "$OUT/catalog.duckdb"
curbside catalog ingest --source procedural --per-category 1 --limit 12 --catalog "$OUT/catalog.duckdb"
curbside catalog eval --limit 12 | tee "$OUT/eval.txt"
cp "$(find "$OUT/catalog_assets/retrieval" -name contact_sheet.png | sort | head -1)" "$OUT/contact_sheet.png"
echo "contact sheet: $OUT/contact_sheet.png"
