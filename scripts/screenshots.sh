#!/usr/bin/env bash
# Takes the README's pictures (docs/*.png) from the examples as they are, so that they never go
# stale: each example runs in a virtual X display (Xvfb), takes a screenshot after 5 s of
# simulation (`CLOTH_EXAMPLE_SCREENSHOT`) and exits. On a machine without a GPU the pictures
# are rendered by Mesa's lavapipe (installed here, as `.ci/run` does), which is slow but the
# same picture.
#
#     bash scripts/screenshots.sh                 # every picture
#     bash scripts/screenshots.sh gltf_character  # one
set -euo pipefail
cd "$(dirname "$0")/.."

examples=("$@")
[ ${#examples[@]} -gt 0 ] || examples=(bunny flag cape character gltf_character tablecloth towel grab many_cloths)

need=()
command -v xvfb-run >/dev/null || need+=(xvfb xauth)
[ -e /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ] || [ -n "$(ls /usr/share/vulkan/icd.d 2>/dev/null)" ] || need+=(mesa-vulkan-drivers)
if [ ${#need[@]} -gt 0 ]; then
    apt-get update -qq && apt-get install -y -qq "${need[@]}" >/dev/null
fi

export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/bevy_bvh_cloth/target}"
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
build=()
for example in "${examples[@]}"; do build+=(--example "$example"); done
cargo build --locked -p bevy_bvh_cloth "${build[@]}"

for example in "${examples[@]}"; do
    out="docs/$example.png"
    rm -f "$out"
    xvfb-run -a -s "-screen 0 1280x720x24" env CLOTH_EXAMPLE_SCREENSHOT="$PWD/$out" BEVY_ASSET_ROOT="$PWD" \
        "$CARGO_TARGET_DIR/debug/examples/$example" >"/tmp/screenshot_$example.log" 2>&1 || true
    if [ -s "$out" ]; then
        echo "$out"
    else
        echo "no picture from $example: see /tmp/screenshot_$example.log" >&2
        exit 1
    fi
done
