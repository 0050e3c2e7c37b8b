#!/usr/bin/env bash
# Scene generation demo: scenes of different block mixes and sidewalk templates, rendered to outputs/scenes/,
# plus a small unseen-split dataset and its statistics figure.
set -euo pipefail
cd "$(dirname "$0")/.."
out=outputs/scenes
mkdir -p "$out"
curbside scenes generate --blocks SXC --seed 1 --templates abc --out "$out/sxc_abc.json"
curbside scenes generate --blocks SOT --seed 2 --templates def --out "$out/sot_def.json"
curbside scenes generate --blocks 4 --seed 3 --templates g --object-density 1.5 --out "$out/random4_g.json"
for s in sxc_abc sot_def random4_g; do
  curbside scenes render "$out/$s.json" --out "$out/$s.png"
done
curbside scenes dataset --split unseen --count 20 --out "$out/unseen_demo"
curbside scenes stats "$out/unseen_demo"
