#!/usr/bin/env bash
# Set up StoryBeam on a fresh Debian machine (Python 3.11, root, no display, no GPU).
# Safe to run twice: apt and pip skip what is already there.
#   - system packages: Mesa EGL/OSMesa for headless pyrender and Kivy, ffmpeg-free MP4 via
#     imageio-ffmpeg's bundled binary, Xvfb for optional UI runs;
#   - a virtual environment in .venv with the project installed (editable) plus dev tools.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES="libegl1 libegl-mesa0 libgl1 libglx-mesa0 libgl1-mesa-dri libopengl0 libosmesa6 libgles2 xvfb xauth libmtdev1 strace glslang-tools libportaudio2"  # glslang-tools: checks the Kivy GL shaders are GLSL ES 1.00; libportaudio2: sounddevice (desktop recording)

missing=""
for p in $APT_PACKAGES; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  echo "[setup] installing system packages:$missing"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $missing
fi

PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
if [ ! -x .venv/bin/python ]; then
  echo "[setup] creating .venv with $PY"
  "$PY" -m venv .venv
fi
stamp=.venv/.storybeam-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "[setup] installing Python packages into .venv"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[dev]"
  touch "$stamp"
fi
echo "[setup] ready: $(.venv/bin/python --version)"

# Compile ahead: the search kernels (numba) compile on their first use, about 8 s on 2 cores,
# and are cached (retrieval/dtw/jit.py: $NUMBA_CACHE_DIR, else $STORYBEAM_CACHE/numba, else
# ~/.cache/storybeam/numba; one sub-folder per version of the kernels' sources). One search
# and one subsequence search of the bundled library compile every kernel the product's search
# path uses, so the first real `storybeam search` (demo, "More like this") loads them in ~20 ms.
# The tests read the same cache (tests/conftest.py), so scripts/test.sh compiles only what the
# tests use beyond the product's path (their oracles), once per version of the kernels.
# Where numba is absent this just runs the numpy path.
echo "[setup] compiling the search kernels ahead (cached; ~10 s the first time)"
Q=assets/motions/bvh/02_01.bvh
.venv/bin/python -m app.cli search --query "$Q" -k 1 --json "${TMPDIR:-/tmp}/storybeam-warm.json" >/dev/null
.venv/bin/python -m app.cli search --query "$Q" -k 1 --subsequence --json "${TMPDIR:-/tmp}/storybeam-warm.json" >/dev/null
rm -f "${TMPDIR:-/tmp}/storybeam-warm.json"
