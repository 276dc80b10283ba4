#!/usr/bin/env bash
# Set everything up (scripts/setup.sh) and run StoryBeam's test suite headless.
#   bash scripts/test.sh           the full suite (the README's test command; CI runs it)
#   bash scripts/test.sh --fast    the fast lane: pytest -m "not slow", the unit tests of every
#                                  package without the app in a subprocess, campaigns, bench
#                                  runs or the shared data (70 s of tests on 2 cores; the full suite 8 min)
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
# Kivy makes its home (.kivy, mods/, icon/, config.ini) on first import, without exist_ok:
# two workers importing it at once on a fresh clone raced to FileExistsError. Make it here, once.
.venv/bin/python -c "import kivy" >/dev/null
# One pytest worker per CPU, at most 4 (each loads numpy, OpenCV and Kivy; the app tests start
# their own child processes); STORYBEAM_TEST_WORKERS overrides, 0 runs in this process.
# --dist loadscope keeps a module's tests on one worker, so a module's app fixture starts once.
workers=${STORYBEAM_TEST_WORKERS:-$(nproc 2>/dev/null || echo 1)}
[ "$workers" -gt 4 ] && [ -z "${STORYBEAM_TEST_WORKERS:-}" ] && workers=4
[ "$workers" -lt 2 ] && workers=0
exec .venv/bin/python -m pytest -q --durations=15 -n "$workers" --dist loadscope ${args[@]+"${args[@]}"}
