#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Render the synthetic skyline training set behind the shipped skyline parameters:
#   tools/skyline_training_set.sh [OUTPUT_DIR]     (default build/skyline_training)
# then: skynav skyline train OUTPUT_DIR/*.mcap --out params.yaml
# Seeds 10-12 in every world style: none of them is a bundled (evaluation) recording, which use seed 4.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-build/skyline_training}
mkdir -p "$out"
for world in garden park mineral; do
    for seed in 10 11 12; do
        file="$out/synthetic_${world}_skyline_seed${seed}.mcap"
        [ -e "$file" ] || .venv/bin/skynav sim bag skyline --world "$world" --seed "$seed" --count 2 \
            --size 320x240 --fov 200 --encoding mono8 --out "$file"
    done
done
