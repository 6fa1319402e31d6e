#!/usr/bin/env bash
# The browser test: builds examples/web_check for WebGPU, serves it, and runs it in headless
# Chromium (its WebGPU adapter is SwiftShader where there is no GPU) twice, once asking for the
# GPU backend and once for the CPU backend. Each run must end in the app's
# `web_check: PASS` on the backend asked for: every particle finite, the cloth resting on its
# ball collider, and the free-falling cloth within 1e-3 m of the core's stepper. The page's
# screenshots are left beside it. `.ci/run` runs it.
#
#   bash scripts/web_check.sh
#
# Installs what is missing: Chromium, python3 and its websocket module (Debian packages), the
# wasm32 target and wasm-bindgen-cli (scripts/web/tools.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/web/tools.sh

need=()
command -v chromium >/dev/null || need+=(chromium)
command -v python3 >/dev/null || need+=(python3)
python3 -c 'import websocket' 2>/dev/null || need+=(python3-websocket)
if [ ${#need[@]} -gt 0 ]; then
    apt-get update -qq && apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
# The python3 first on the PATH may not be Debian's (pyenv's, say), and then it does not see
# the module the package installed: the check runs on Debian's where that one has it, else the
# module is installed for the python3 on the PATH.
python=python3
if ! python3 -c 'import websocket' 2>/dev/null; then
    if /usr/bin/python3 -c 'import websocket' 2>/dev/null; then
        python=/usr/bin/python3
    else
        python3 -m pip install --quiet websocket-client
    fi
fi
web_tools

target=${CARGO_TARGET_DIR:-$HOME/.cache/bevy_bvh_cloth/target}
out=$target/web/web_check
# `.ci/run`'s `ci` profile (the dependencies not optimised, the core optimised, no debug info: a
# quick build that runs fast enough). Without the `egui` feature: the check shows no panel, and
# the panel and its font and text stack would add 69 crates to the 280 the check builds.
CARGO_TARGET_DIR=$target cargo build --locked -p bevy_bvh_cloth --example web_check \
    --target wasm32-unknown-unknown --features bevy/webgpu --profile ci
rm -rf "$out"
wasm-bindgen --target web --no-typescript --out-dir "$out" --out-name web_check \
    "$target/wasm32-unknown-unknown/ci/examples/web_check.wasm"
cp scripts/web/check.html "$out/index.html"
cp scripts/web/start.js "$out/"

# A free port, so that a server left on a fixed one cannot answer with another build.
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
python3 -m http.server --directory "$out" --bind 127.0.0.1 "$port" >/dev/null 2>&1 &
server=$!
trap 'kill $server 2>/dev/null' EXIT
sleep 1
kill -0 "$server" 2>/dev/null || { echo "web check: the page's server did not start on port $port" >&2; exit 1; }
# Both backends at once, each in its own Chromium (one after the other took 179 s on the 2-core
# machine, side by side 162 s). Each log is shown when both are done.
pids=()
for backend in gpu cpu; do
    "$python" scripts/web/check.py "http://127.0.0.1:$port/?backend=$backend" "${backend^^}" \
        "$out/web_check_$backend.png" 300 >"$out/web_check_$backend.log" 2>&1 &
    pids+=("$!")
done
failed=0
for i in 0 1; do
    wait "${pids[$i]}" || failed=1
done
for backend in gpu cpu; do
    echo "web check, ${backend^^} backend:"
    cat "$out/web_check_$backend.log"
done
exit "$failed"
