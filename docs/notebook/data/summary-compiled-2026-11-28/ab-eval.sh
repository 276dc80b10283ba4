#!/usr/bin/env bash
# A/B through the command: old (42c8616) vs now, bandai2 + cmu, alternated, one pinned core, one thread.
set -u
out=/work/ba/s5/abeval; mkdir -p $out
export KIVY_NO_ARGS=1 KIVY_NO_CONSOLELOG=1 SDL_VIDEODRIVER=offscreen PYOPENGL_PLATFORM=egl MPLBACKEND=Agg OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
PY=/work/main/.venv/bin/python
for i in $(seq ${1:-5}); do
  for side in old new; do
    dir=/work/main; [ $side = old ] && dir=/tmp/old42
    for d in bandai2 cmu; do
      (cd $dir && PYTHONPATH=$dir taskset -c 1 $PY -m app.cli eval --data /work/shared/data/$d --methods storybeam --split random,subject --json $out/${d}_${side}_$i.json > $out/${d}_${side}_$i.log 2>&1)
    done
    echo "done $side $i $(date +%T)" >> $out/progress
  done
done
