#!/usr/bin/env bash
# What the app's own doings do to the frame-time promise, in an app as a user writes it
# (`sherwood-lab user-app`, lab/src/user_app.rs: DefaultPlugins, Bevy's default present mode and multisampling,
# the default forest, a still camera), windowed under Xvfb:
#   - a +STEP_MS and then a −STEP_MS step of game logic (a busy `Update` system),
#   - SPHERES PBR spheres spawned at once,
#   - the 40 glTF rocks with `_LOD` levels (assets/props/rocks.glb) beside the forest,
#     against the same target without them,
# each line reporting the mean period, the share over 1.1 × target, the frames over it
# among the 20 after each event and how far the primitives swing (std / mean). The noise
# floor (static LOD: identical frames) is measured in every round.
#
#   scripts/app_events.sh            # 3 rounds
#
# Override ROUNDS, FRAMES, TARGET_MS (the step runs), SPHERES_TARGET_MS, PROPS_TARGET_MS,
# STEP_MS, SPHERES, EXTRA (more user_app flags, e.g. "--msaa 1"), CARGO_FLAGS and OUT
# (results/app_events). Each target must leave room above the floors (the forest's
# cheapest representations, the terrain, the spheres, the rocks at their coarsest pixels):
# below it no budget holds, and the prediction says so (`predicted_ms` over the target).
set -euo pipefail
cd "$(dirname "$0")/.."

ROUNDS=${ROUNDS:-3}
FRAMES=${FRAMES:-300}
TARGET_MS=${TARGET_MS:-80}
SPHERES_TARGET_MS=${SPHERES_TARGET_MS:-120}
PROPS_TARGET_MS=${PROPS_TARGET_MS:-140}
STEP_MS=${STEP_MS:-30}
SPHERES=${SPHERES:-20}
EXTRA=${EXTRA:-}
OUT=${OUT:-results/app_events}
mkdir -p "$OUT"
target_dir=${CARGO_TARGET_DIR:-target}

# shellcheck disable=SC2086
cargo build --release ${CARGO_FLAGS:-} --bin sherwood-lab
user_app=("$target_dir/release/sherwood-lab" user-app)
export BEVY_ASSET_ROOT=$PWD
run() {
    local name=$1
    shift
    # shellcheck disable=SC2086
    xvfb-run -a -s "-screen 0 1280x720x24" "${user_app[@]}" $EXTRA --frames "$FRAMES" "$@" \
        | sed "s/^user_app /user_app run=$name /" | tee -a "$OUT/$name.txt"
}

for round in $(seq 1 "$ROUNDS"); do
    echo "== round $round"
    run noise --mode static --target-ms "$TARGET_MS"
    run step --target-ms "$TARGET_MS" --step-ms "$STEP_MS"
    run spheres --target-ms "$SPHERES_TARGET_MS" --spawn-spheres "$SPHERES"
    run props --target-ms "$PROPS_TARGET_MS" --props
    run no_props --target-ms "$PROPS_TARGET_MS"
done
