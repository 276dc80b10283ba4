#!/usr/bin/env bash
# Set everything up (scripts/setup.sh) and run StoryBeam's test suite headless.
#   bash scripts/test.sh           the full suite (the README's test command; CI runs it)
#   bash scripts/test.sh --fast    the fast lane: pytest -m "not slow", the unit tests of every
#                                  package without the app in a subprocess, campaigns, bench
#                                  runs or the shared data (under 2 minutes on 2 cores)
# Other arguments go to pytest, e.g. `bash scripts/test.sh --fast -k dtw`.
# The numba kernels come from the cache setup.sh has just warmed (tests/conftest.py reads it).
set -euo pipefail
cd "$(dirname "$0")/.."
args=()
for a in "$@"; do
  if [ "$a" = "--fast" ]; then args+=(-m "not slow"); else args+=("$a"); fi
done
bash scripts/setup.sh
export PYOPENGL_PLATFORM=${PYOPENGL_PLATFORM:-egl}
export SDL_VIDEODRIVER=${SDL_VIDEODRIVER:-offscreen}
export KIVY_NO_ARGS=1 KIVY_NO_CONSOLELOG=1
export KIVY_HOME=${KIVY_HOME:-$PWD/.kivy}
export MPLBACKEND=Agg
exec .venv/bin/python -m pytest -q --durations=15 ${args[@]+"${args[@]}"}
