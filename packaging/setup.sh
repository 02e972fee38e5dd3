#!/usr/bin/env bash
# Sets up everything Scanlight needs on a fresh Debian/Ubuntu machine:
#   1. system packages (Mesa EGL/GL for headless rendering, libusb for open3d, Xvfb for the
#      window tests), installed with apt-get when missing and permitted;
#   2. a virtual environment in .venv with Scanlight and its pinned dependencies.
# Re-running is cheap: pip runs again only when pyproject.toml changed.
set -euo pipefail
cd "$(dirname "$0")/.."

SYSTEM_PACKAGES=(libusb-1.0-0 xvfb xauth libegl1 libgl1 libgl1-mesa-dri)
missing=()
for pkg in "${SYSTEM_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
    if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then SUDO="sudo -n"; else SUDO=none; fi
    if [ "$SUDO" = none ] || ! command -v apt-get >/dev/null; then
        echo "scanlight setup: missing system packages: ${missing[*]}" >&2
        echo "scanlight setup: install them with: sudo apt-get install -y ${missing[*]}" >&2
        exit 1
    fi
    echo "scanlight setup: installing system packages: ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    echo "scanlight setup: creating .venv with $($PYTHON --version)"
    "$PYTHON" -m venv .venv
fi
stamp=.venv/.scanlight-installed
want=$(cat pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
    echo "scanlight setup: installing Python packages into .venv (first run takes a few minutes)"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -e ".[dev]"
    echo "$want" > "$stamp"
fi
