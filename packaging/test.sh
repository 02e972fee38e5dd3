#!/usr/bin/env bash
# README command 2: set everything up, then run the whole test suite (window tests on Xvfb).
set -euo pipefail
cd "$(dirname "$0")/.."
bash packaging/setup.sh
export PYTHONUNBUFFERED=1
if [ -z "${DISPLAY:-}" ]; then
    exec xvfb-run -a -s "-screen 0 1600x1000x24" .venv/bin/python -m pytest "$@"
fi
exec .venv/bin/python -m pytest "$@"
