#!/usr/bin/env bash
# Takes the README screenshot of the real viewer window (under Xvfb when there is no display):
# the demo scene after an HDR expansion, fully refined, written to assets/screenshot.png.
set -euo pipefail
cd "$(dirname "$0")/.."
exec .venv/bin/python -m app.ui.screenshot --out assets/screenshot.png "$@"
