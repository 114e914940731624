#!/usr/bin/env bash
# The prepared checks for a session lent the GPU machine (one H200, 16 Intel cores; 15 minutes of device time):
# issue 57's goldens on another CPU family, then issue 58's measurements (benchmarks/gpu.py), in about 10 minutes.
#
# That machine has python3 3.12 with torch, numba, numba-cuda, numpy, pyyaml, rich, pytest and hypothesis, but no
# network: gymnasium, pettingzoo and array-api-compat (a core dependency since issue 67) travel as wheels. Once, here, in
# the repository's root:
#
#   echo /.whl/ >> .git/info/exclude
#   python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#       --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
#       -d .whl gymnasium==1.2.2 farama-notifications==0.0.6 pettingzoo==1.27.0 array-api-compat==1.16.0
#
# Then one device call: run(command='bash benchmarks/gpu_session.sh', carry=['.whl'], timeout_s=600), and commit
# what comes back (golden.log, gpu.json, gpu.log) with the figures in docs/performance.md.
#
# Caveat for issue 57: that machine's torch is its own (2.11 with CUDA), not the pinned 2.13 CPU wheel (too large to
# carry), so a golden that differs there may differ by torch version rather than CPU family; one that holds is
# evidence for the CPU family.
set -o pipefail
export PYTHONUNBUFFERED=1 SDL_VIDEODRIVER=dummy
OUT=${OUT:-/tmp/gpu-session}
mkdir -p "$OUT"
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
    || exit 1
export PYTHONPATH="$PWD:/tmp/site"
{ lscpu | grep -E 'Model name|^CPU\(s\)'; nvidia-smi -L
  python3 -c 'import torch, numba; print(torch.__version__, numba.__version__)'; } 2>&1 | tee "$OUT/machine.log"
# the golden runs on this CPU (bitwise where it is the recordings' machine, within the measured tolerance elsewhere)
# and the batched evaluation (about 2 minutes); --check prints how far each variant parts from its recording
timeout 200 python3 -m pytest -q -p no:cacheprovider tests/learn/test_golden.py \
    tests/learn/test_batched_evaluation.py 2>&1 | tee "$OUT/golden.log"
MATE_REPRODUCIBLE=1 timeout 120 python3 tests/learn/golden.py --check 2>&1 | tee "$OUT/golden-check.log"
# issue 58: the device core, the whole game, rollouts and greedy vs greedy (benchmarks/gpu.py's docstring)
timeout 350 python3 benchmarks/gpu.py --seconds 2 --train-seconds 15 --json "$OUT/gpu.json" 2>&1 | tee "$OUT/gpu.log"
