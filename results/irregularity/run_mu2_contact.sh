#!/bin/sh
# Seeds 1 and 2 of German low, German high and FRA class 6 over the whole mu2 set (185 bridges x
# ICE-2, Railjet = 370 cases each), every case computed afresh with the code of the commit (the DIM's
# contact check included), settings of run_mu2_seed1.sh / run_mu2_seed2.sh (paper DIM grid, 160..350
# km/h at 1 km/h). OUT: a root for the six study directories that holds none of them yet (a study
# resumes a directory that holds results, so an old run would be kept, not recomputed).
# From the repository root:
#   OUT=/tmp/irregularity_rerun nohup sh results/irregularity/run_mu2_contact.sh > run_mu2_contact.log 2>&1 &
set -e
ADM_CALIB=${ADM_CALIB:-.venv/bin/adm-calib}
OUT=${OUT:?set OUT to a new directory}
WORKERS=${WORKERS:-2}
for seed in 1 2; do
  for spec in german-low german-high fra-6; do
    if [ -e "$OUT/$spec-s$seed/results.jsonl" ] && [ ! -e "$OUT/$spec-s$seed/.started-here" ]; then
      echo "error: $OUT/$spec-s$seed already holds results from elsewhere; choose a new OUT" >&2
      exit 2
    fi
    mkdir -p "$OUT/$spec-s$seed" && touch "$OUT/$spec-s$seed/.started-here"
    echo "== $(date -u +%H:%M:%S) $spec seed $seed: start"
    "$ADM_CALIB" study --out "$OUT/$spec-s$seed" --trains ICE-2,Railjet --mass-functions mu2 \
      --dim-grid paper --irregularity "$spec:seed=$seed" --workers "$WORKERS"
    echo "== $(date -u +%H:%M:%S) $spec seed $seed: done"
  done
done
