#!/bin/sh
# German low, German high and FRA class 6, seed 2, over the whole mu2 set (185 bridges x ICE-2,
# Railjet = 370 cases each), continuing the slice's study directories (their 60 cases are kept, the
# other 310 run), with the settings of run_mu2_seed1.sh. One worker process (the machine is shared).
# From the repository root:
#   PYTHONPATH=src nohup sh results/irregularity/run_mu2_seed2.sh > results/irregularity/run_mu2_seed2.log 2>&1 &
set -e
ADM_CALIB=${ADM_CALIB:-/work/main/.venv/bin/adm-calib}
for spec in german-low german-high fra-6; do
  echo "== $(date -u +%H:%M:%S) $spec seed 2: start"
  "$ADM_CALIB" study --out "results/irregularity/runs/$spec-s2" --trains ICE-2,Railjet --mass-functions mu2 \
    --dim-grid paper --irregularity "$spec:seed=2" --workers 1
  echo "== $(date -u +%H:%M:%S) $spec seed 2: done"
done
