#!/usr/bin/env bash
# README command 1: set everything up, then open the viewer on the built-in demo scene
# (on a machine with no display, `scanlight view` says so and runs the headless demo instead).
set -euo pipefail
cd "$(dirname "$0")/.."
bash packaging/setup.sh
exec .venv/bin/scanlight view "$@"
