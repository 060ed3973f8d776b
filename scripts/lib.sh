# Shared helpers of the stride scripts; sourced, not run.
# shellcheck shell=bash

STRIDE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export STRIDE_ROOT

# Debian packages the workspace needs to build, test and run.
STRIDE_PACKAGES=(
    liblcm-dev liblcm-bin liblcm-java # the C LCM library, its tools, its Java jar
    libglib2.0-dev                    # lcm.pc requires glib's .pc files
    libclang-dev                      # bindgen
    pkg-config gcc libc6-dev          # finding and building against liblcm
    g++                               # the Due firmware's host syntax check (scripts/firmware)
    gcc-avr avr-libc                  # the link codec built for the ATmega32U4 (scripts/firmware)
    iproute2 util-linux               # ip, unshare: the private test network
    openssl                           # the Zenoh link's certificates (scripts/zenoh-certs)
    python3 python3-pip python3-venv  # bench tables; the newer-liblcm check; the peers' venv
    default-jdk-headless libjchart2d-java # the Java types and lcm-spy (scripts/spy)
)

say() {
    if [ -t 2 ]; then printf '\033[1m==> %s\033[0m\n' "$*" >&2; else printf '==> %s\n' "$*" >&2; fi
}
die() { printf 'error: %s\n' "$*" >&2; exit 1; }

as_root() {
    if [ "$(id -u)" = 0 ]; then "$@"
    elif command -v sudo >/dev/null; then sudo "$@"
    else die "need root (or sudo) to run: $*"
    fi
}

# Installs whichever of STRIDE_PACKAGES (plus any given) are missing; does nothing otherwise.
ensure_packages() {
    local missing=() p
    for p in "${STRIDE_PACKAGES[@]}" "$@"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
    done
    [ ${#missing[@]} -eq 0 ] && return 0
    say "installing system packages: ${missing[*]}"
    as_root env DEBIAN_FRONTEND=noninteractive apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

ensure_rust() {
    [ -d "$HOME/.cargo/bin" ] && export PATH="$HOME/.cargo/bin:$PATH"
    command -v cargo >/dev/null || die "cargo not found: install a Rust toolchain (1.80 or newer), e.g. with rustup"
}

# Everything a fresh Debian machine needs before cargo can build the workspace.
bootstrap() {
    ensure_packages "$@"
    ensure_rust
    cd "$STRIDE_ROOT"
}

# The third-party peers of the conformance tests (python-can, python-canopen, dynamixel_sdk),
# pinned in tests/peers/requirements.txt, in a venv under target/peers; installed again only
# when the requirements change. Exports STRIDE_PEERS_PYTHON.
ensure_peers() {
    local venv="$STRIDE_ROOT/target/peers" req="$STRIDE_ROOT/tests/peers/requirements.txt"
    local stamp="$venv/.requirements"
    if [ ! -x "$venv/bin/python" ] || ! cmp -s "$req" "$stamp"; then
        say "installing the third-party peers into target/peers (tests/peers/requirements.txt)"
        rm -rf "$venv"
        python3 -m venv "$venv"
        "$venv/bin/pip" install -q --disable-pip-version-check -r "$req"
        cp "$req" "$stamp"
    fi
    export STRIDE_PEERS_PYTHON="$venv/bin/python"
}

# Runs a command inside a private network namespace whose only interface is a loopback with a
# multicast route, so LCM's UDP multicast never reaches the host's interfaces. Inside it,
# STRIDE_NETNS=1 is set (tests that need multicast check for it).
in_netns() {
    if [ -n "${STRIDE_NETNS:-}" ]; then "$@"; return; fi
    local unshare=(unshare --net)
    [ "$(id -u)" = 0 ] || unshare=(unshare --user --map-root-user --net)
    "${unshare[@]}" -- bash -c '
        set -e
        ip link set lo up
        ip route add 224.0.0.0/4 dev lo
        export STRIDE_NETNS=1
        exec "$@"' stride-netns "$@"
}
