#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Regenerate the bundled synthetic recordings: bags/generate.sh [OUTPUT_DIR]
# Every file is rendered by skynav_sim from the seeds below; the same commands
# give the same bytes. See bags/README.md for what each one is for.
set -euo pipefail
cd "$(dirname "$0")"
out=${1:-.}
sim() { ../.venv/bin/skynav sim bag "$@"; }
common=(--size 320x240 --fov 200 --encoding mono8)

# Teach and repeat drives along one route: other time of day, sideways offset, extra shake, and a
# heading that wanders 25 degrees (rms) about the route's, as a mower's does while it steers.
sim teach   --world garden  --seed 1 --length 8 --speed 1.0 --time forenoon "${common[@]}" \
    --out "$out/synthetic_garden_teach.mcap"
sim repeat  --world garden  --seed 1 --length 8 --speed 0.9 --time morning --clouds 0.3 \
    --offset 0.25 --shake 3 --wobble 25 "${common[@]}" --out "$out/synthetic_garden_repeat.mcap"
sim teach   --world mineral --seed 2 --length 6 --speed 1.0 --time noon "${common[@]}" \
    --out "$out/synthetic_mineral_teach.mcap"
sim repeat  --world mineral --seed 2 --length 6 --speed 0.9 --time sunrise \
    --offset -0.2 --shake 3 --wobble 25 "${common[@]}" --out "$out/synthetic_mineral_repeat.mcap"
# The garden repeat with a detour: in the route's middle a loop off it reaching 4.3 m away, then back on the route;
# a frame every 0.2 m (2 m/s at 10 Hz, or a mower's 0.5 m/s at 2.5 Hz) keeps the file small.
sim repeat  --world garden  --seed 1 --length 8 --speed 2.0 --time morning --clouds 0.3 \
    --offset 0.25 --shake 3 --wobble 25 --detour 4 "${common[@]}" --out "$out/synthetic_garden_detour.mcap"

# A snapshot place and a 7 x 7 grid of places 0.75 m apart around it; then the same on bumpy ground, every
# place (the snapshot's too) on a bump that tilts the camera up to 20 degrees more.
sim homing  --world park    --seed 3 --spacing 0.75 --grid-radius 2.25 --time forenoon "${common[@]}" \
    --out "$out/synthetic_park_homing.mcap"
sim homing  --world park    --seed 3 --spacing 0.75 --grid-radius 2.25 --time forenoon --bump-tilt 20 \
    "${common[@]}" --out "$out/synthetic_park_bumpy_homing.mcap"

# One place: a reference view, 15 rotations (tilt up to 30 degrees), 15 views up to 0.5 m away.
sim compass --world garden  --seed 1 --count 15 --max-tilt 30 --max-translation 0.5 --time forenoon \
    "${common[@]}" --out "$out/synthetic_garden_compass.mcap"
sim compass --world mineral --seed 2 --count 15 --max-tilt 30 --max-translation 0.5 --time noon \
    "${common[@]}" --out "$out/synthetic_mineral_compass.mcap"

# The garden repeat drive through one colour camera delivering JPEG on /camera/image_raw/compressed (what most
# drivers deliver), at image_transport's default quality (95).
sim repeat  --world garden  --seed 1 --length 8 --speed 0.9 --time morning --clouds 0.3 \
    --offset 0.25 --shake 3 --wobble 25 --size 320x240 --fov 200 --camera colour-compressed --codec jpeg \
    --jpeg-quality 95 --out "$out/synthetic_garden_colour_repeat.mcap"

# Labelled skyline sets: 2 places at each of 5 times of day, clear and cloudy, in each world style.
for world in garden park mineral; do
    sim skyline --world "$world" --seed 4 --count 2 "${common[@]}" --out "$out/synthetic_${world}_skyline.mcap"
done
