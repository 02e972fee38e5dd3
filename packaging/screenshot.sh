#!/usr/bin/env bash
# Takes the README screenshot of the real viewer window (under Xvfb when there is no display):
# the demo scene after an HDR expansion, fully refined, written to assets/screenshot.png.
# The viewer's automation option runs app/ui/screenshot.py after every frame; extra arguments go
# to `scanlight view`, e.g. --size 1600x900, --script-arg expand=no.
set -euo pipefail
cd "$(dirname "$0")/.."
cmd=(.venv/bin/python -m app view --size 1280x800 --script app/ui/screenshot.py
     --script-arg out=assets/screenshot.png "$@")
if [ -z "${DISPLAY:-}" ]; then
    exec xvfb-run -a -s "-screen 0 1600x1000x24" "${cmd[@]}"
fi
exec "${cmd[@]}"
