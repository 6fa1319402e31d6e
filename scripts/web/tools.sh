# Sourced by the web scripts: `web_tools` installs what building for the browser needs and is
# missing, the wasm32-unknown-unknown target and wasm-bindgen-cli at the version Cargo.lock pins.
web_tools() {
    rustup target list --installed | grep -qx wasm32-unknown-unknown || rustup target add wasm32-unknown-unknown
    local version
    version=$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)
    if [ "$(wasm-bindgen --version 2>/dev/null | cut -d' ' -f2)" != "$version" ]; then
        # Its own lock file first; a registry that lacks one of its pinned versions gets the
        # newest compatible ones instead. Forced: cargo skips a version it has on record even
        # when the binary is gone.
        # Only the `wasm-bindgen` binary, without the test runner's TLS stack. Built without
        # optimisation or debug info: on the 2-core machine it built in 87 s against 201 s
        # optimised (190 s at opt-level 1) and binds the browser check's 87 MB page in 71 s
        # against 17 s, so a fresh machine, which does both once, is done about 60 s sooner.
        local install=(env CARGO_PROFILE_DEV_DEBUG=0 cargo install wasm-bindgen-cli --version "$version"
            --no-default-features --bin wasm-bindgen --debug --force)
        "${install[@]}" --locked || "${install[@]}"
    fi
}
