#!/usr/bin/env bash
# Set everything up (scripts/setup.sh) and run StoryBeam's test suite headless.
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -k dtw`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-egl}
export SDL_VIDEODRIVER=${SDL_VIDEODRIVER:-offscreen}
export KIVY_NO_ARGS=1 KIVY_NO_CONSOLELOG=1
export KIVY_HOME=${KIVY_HOME:-$PWD/.kivy}
export MPLBACKEND=Agg
exec .venv/bin/python -m pytest -q --durations=15 "$@"
