#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Every evaluation on the four real Stellarium landscapes (docs/results.md): render the sets into
# OUT_DIR (default build/landscapes; the renders hold GPL data, never commit them), then print the skyline,
# compass (snapshot at the views' time and at noon; SH degree 16 and 32) and localization tables, with a map
# built from each landscape's teach drive. About 10 minutes on one core. Run after `make setup`.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build/landscapes}
mkdir -p "$out"
skynav=.venv/bin/skynav
common="--size 320x240 --encoding mono8"
printf 'sh:\n  ros__parameters:\n    max_degree: 32\n' > "$out/degree32.yaml"
render() {  # render FILE ARGS...: skip sets already rendered
  local file=$1; shift
  [ -f "$out/$file" ] || "$skynav" sim bag "$@" $common --out "$out/$file" 2>/dev/null
}
for W in garching guereins hurricane geneva; do
  render skyline_$W.mcap skyline --world $W --seed 4 --count 2
  render compass_$W.mcap compass --world $W --seed 1 --count 40 --max-tilt 30 --time morning
  render compass_noon_$W.mcap compass --world $W --seed 1 --count 40 --max-tilt 30 --time morning --reference-time noon
  render teach_$W.mcap teach --world $W --seed 1 --length 8 --speed 1.0 --time forenoon
  render repeat_$W.mcap repeat --world $W --seed 1 --length 8 --speed 0.9 --time morning --clouds 0.3 \
    --offset 0.25 --shake 3 --wobble 25
done
echo "== skyline"
"$skynav" skyline eval "$out"/skyline_*.mcap --plot "$out/skyline_histogram.png"
for W in garching guereins hurricane geneva; do
  for set in compass compass_noon; do
    echo "== compass: $set $W, SH degree 16"
    "$skynav" eval compass "$out/${set}_$W.mcap" --methods fft-masked fft-masked-any-tilt --plots "$out/plots"
    echo "== compass: $set $W, SH degree 32"
    "$skynav" eval compass "$out/${set}_$W.mcap" --methods fft-masked --params "$out/degree32.yaml" \
      --plots "$out/plots32"
  done
  echo "== localization: $W"
  "$skynav" map build "$out/teach_$W.mcap" --out "$out/map_$W.db" --overwrite --baselines
  "$skynav" eval localization "$out/repeat_$W.mcap" --map "$out/map_$W.db" --plots "$out/plots"
done
