export KIVY_NO_ARGS=1 OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
data=${1:-bandai2}; n=${2:-5}
for i in $(seq $n); do for side in old42 main; do d=/tmp/old42; [ $side = main ] && d=/work/main
 echo "$side $data $i $(cd $d && PYTHONPATH=$d taskset -c 1 /work/main/.venv/bin/python /work/ba/s4/steptime.py /work/shared/data/$data 4)"; done; done
