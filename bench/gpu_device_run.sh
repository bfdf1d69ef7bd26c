#!/bin/bash
# One run on a lent GPU machine (the workplace's `device` tool), within its 15 minutes:
#   the dexel and sim sections of bench/gpu.py, the CUDA parity checks on the GPU, then the
#   Tableau 7 and 8 sweeps, each under its own time limit, every log and JSON under $OUT, with a
#   cProfile of each section's last row (prof.tgz: where the host's time goes beside the kernels).
# Before it, here: wheels of numpy 2.4.x (cp312, manylinux) and trimesh in .whl/ (bench/README.md,
# gpu.py). Run there as:  bash bench/gpu_device_run.sh   (carry .whl)
# Afterwards, here:  .venv/bin/python bench/gpu.py --tables <its gpu_*.json> bench/gpu_cpu_2core.json
export PYTHONUNBUFFERED=1
t0=$SECONDS
OUT=${OUT:-bench/out/device}
mkdir -p "$OUT"
[ -n "$SKIP_INSTALL" ] || python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl || exit 3
export PYTHONPATH=/tmp/site:$PWD/src NUMBA_CACHE_DIR=/tmp/nbcache
PY=${PY:-python3}
EXTRA="${EXTRA:---repeat 2} --profile $OUT/prof"
{ nvidia-smi; nproc; $PY -c "import numpy, numba, trimesh; from numba import cuda; print(numpy.__version__,
numba.__version__, trimesh.__version__, cuda.is_available())"; } > "$OUT/env.txt" 2>&1
cat "$OUT/env.txt"; echo "setup $((SECONDS - t0)) s"
DS=${DS-dexel,sim}  # DS= (empty) leaves these sections out
[ -z "$DS" ] || timeout "${DS_S:-170}" $PY bench/gpu.py $EXTRA --devices cuda --sections $DS --out "$OUT/gpu_ds.json" \
    > "$OUT/gpu_ds.log" 2>&1
echo "$DS rc=$? at $((SECONDS - t0)) s"
NUMBA_ENABLE_CUDASIM=${SIM:-0} timeout "${PAR_S:-170}" $PY -m pytest -q -p no:cacheprovider tests/cudasim \
    > "$OUT/parity.log" 2>&1
echo "parity rc=$? at $((SECONDS - t0)) s"
left=$(( ${TOTAL_S:-540} - (SECONDS - t0) )); [ $left -gt 5 ] || left=5
timeout $left $PY bench/gpu.py $EXTRA --devices cuda --sections ${TS:-t7,t8} ${T8_ROWS:+--t8-rows $T8_ROWS} \
    --out "$OUT/gpu_t.json" > "$OUT/gpu_t.log" 2>&1
echo "${TS:-t7,t8} rc=$? at $((SECONDS - t0)) s"
tar czf "$OUT/prof.tgz" -C "$OUT" prof && rm -r "$OUT/prof"  # the device tool brings back at most 8 files
for f in "$OUT"/*.log; do echo "== $f"; tail -4 "$f"; done
