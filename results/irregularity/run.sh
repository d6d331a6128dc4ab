#!/bin/sh
# The irregularity slice: ICE-2 and Railjet over the mu2 set (185 bridges each), German low and
# high disturbance and FRA class 6, seeds 1..5; one study directory per (spectrum, seed), seed-major
# order so that an interrupted run leaves whole seeds. Resumable: rerun the same script (every
# study skips the cases already in its results.jsonl).
#   nohup sh results/irregularity/run.sh > results/irregularity/run.log 2>&1 &
cd "$(dirname "$0")/../.." || exit 1
PY=${PY:-/work/main/.venv/bin/python}
export PYTHONPATH="$PWD/src"
for seed in 1 2 3 4 5; do
  for spec in german-low german-high fra-6; do
    out=results/irregularity/runs/$spec-s$seed
    echo "== $(date -u +%FT%TZ) $spec seed $seed"
    "$PY" -m adm_calib.calib_commands study --out "$out" --trains ICE-2,Railjet --mass-functions mu2 \
      --irregularity "$spec:seed=$seed" --workers "${WORKERS:-2}" || exit $?
  done
done
echo "== $(date -u +%FT%TZ) done"
