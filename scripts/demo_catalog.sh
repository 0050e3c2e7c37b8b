#!/usr/bin/env bash
# Demo of the asset catalog: build it from the procedural library, search it, summarise and validate it,
# and write a contact sheet of one variant per category to outputs/.
set -euo pipefail
cd "$(dirname "$0")/.."
export HF_HUB_OFFLINE=1 TRANSFORMERS_OFFLINE=1
CATALOG="${CATALOG:-catalogs/default.duckdb}"
mkdir -p outputs

echo "-- curbside catalog build"
curbside catalog build --catalog "$CATALOG" --variants 3 --seed 0

for q in "fire hydrant" "somewhere to sit" "garbage can" "street light" "red mailbox"; do
  echo "-- curbside catalog query \"$q\""
  curbside catalog query "$q" --catalog "$CATALOG" --limit 3
done
echo "-- a filtered query: short clutter for the clear path"
curbside catalog query "something left on the pavement" --catalog "$CATALOG" --object-class clutter --max-height 1.0 --limit 5
echo "-- JSON output (first result)"
curbside catalog query "fire hydrant" --catalog "$CATALOG" --json --limit 5 \
  | python3 -c "import json, sys; r = json.load(sys.stdin)['results'][0]; print(r['asset_id'], r['category'], round(r['score'], 3))"

echo "-- curbside catalog stats"
curbside catalog stats --catalog "$CATALOG"
curbside catalog stats --catalog "$CATALOG" --json > outputs/catalog_stats.json
echo "-- curbside catalog validate"
curbside catalog validate --catalog "$CATALOG"
curbside catalog export --catalog "$CATALOG" --format parquet --out outputs/catalog_assets.parquet
curbside catalog contact-sheet --seed 0 --out outputs/catalog_contact_sheet.png
echo "catalog demo: $CATALOG, outputs/catalog_contact_sheet.png, outputs/catalog_stats.json, outputs/catalog_assets.parquet"
