#!/usr/bin/env bash
# Builds an example for the browser and serves it locally: the WebGPU build where the browser
# has WebGPU (the GPU backend runs the real kernels), the WebGL2 build elsewhere (no compute
# shaders there, so the CPU backend runs, on one thread).
#
#   bash scripts/web.sh [example] [port]      # default: flag 8080; open http://localhost:8080
#   WEB_BUILD_ONLY=1 bash scripts/web.sh      # build, do not serve
#
# Builds in the workspace's `web` profile (release optimised for size, with link-time
# optimisation: about 18 minutes from clean on two cores). Installs what is missing: the
# wasm32-unknown-unknown target and wasm-bindgen-cli at the version Cargo.lock pins. With a
# binaryen `wasm-opt` of version 116 or later on the PATH (`cargo install wasm-opt --locked`
# builds one), the .wasm is shrunk further with `wasm-opt -Oz`; Debian's binaryen 108 breaks the
# page's function table ("WebAssembly.Table.set(): Argument 1 is invalid") and is not used.
# Serves with python3. The page is written to $CARGO_TARGET_DIR/web/<example> (by default under
# ~/.cache/bevy_bvh_cloth/target-web).
set -euo pipefail
cd "$(dirname "$0")/.."
example=${1:-flag}
port=${2:-8080}
target=${CARGO_TARGET_DIR:-$HOME/.cache/bevy_bvh_cloth/target-web}
out=$target/web/$example

source scripts/web/tools.sh
web_tools

# The features the examples show natively beyond what the browser check needs (the
# target-specific dev-dependencies in crates/bevy_bvh_cloth/Cargo.toml): PBR materials, lookup
# tables for the tone mapping, PNG textures, the glTF character.
shown=bevy/bevy_pbr,bevy/tonemapping_luts,bevy/zstd_rust,bevy/png,bevy/bevy_gltf,bevy/gltf_animation,bevy/reflect_auto_register

rm -rf "$out"
for api in webgpu webgl2; do
    # Bevy's `webgpu` feature takes over from `webgl2`, so each API is a build of its own.
    CARGO_TARGET_DIR=$target cargo build --profile web --locked -p bevy_bvh_cloth --example "$example" \
        --target wasm32-unknown-unknown --features "egui,bevy/$api,$shown"
    wasm-bindgen --target web --no-typescript --out-dir "$out/$api" --out-name "$example" \
        "$target/wasm32-unknown-unknown/web/examples/$example.wasm"
    wasm="$out/$api/${example}_bg.wasm"
    binaryen=$(wasm-opt --version 2>/dev/null | grep -o 'version [0-9]*' | cut -d' ' -f2 || true)
    if [ "${binaryen:-0}" -ge 116 ]; then
        wasm-opt -Oz --enable-bulk-memory --enable-nontrapping-float-to-int --enable-sign-ext \
            --enable-mutable-globals --enable-reference-types --enable-multivalue "$wasm" -o "$wasm.opt"
        mv "$wasm.opt" "$wasm"
    fi
    echo "web.sh: $api build $(du -h "$wasm" | cut -f1), $(gzip -c "$wasm" | wc -c | numfmt --to=iec) gzipped ($wasm)"
done
cp -r assets "$out/assets"
sed "s/EXAMPLE/$example/g" scripts/web/index.html >"$out/index.html"
cp scripts/web/start.js "$out/"

[ -n "${WEB_BUILD_ONLY:-}" ] && exit 0
echo "web.sh: serving $out on http://localhost:$port (Ctrl+C stops)"
exec python3 -m http.server --directory "$out" "$port"
