#!/usr/bin/env bash
# The readings study (docs/REPRODUCTION.md, "Does the duo result hinge on our reading?"): setup duo with k=1, k=2
# and the homogeneous team under the SPEC reading and under each single alternative reading of SPEC section 8
# (env.reward, env.speed, env.poi_type, evaluation.fresh_ic, and the mutation sigma read as a variance); then, for
# every reading that lifts duo, solo k=1 under it, and duo under the combination of the lifting readings. Then the
# compact results (RESULTS/readings.json) and the report (RESULTS/readings.md).
# Resumable: rerun it after an interruption; finished runs are skipped, unfinished ones resume from checkpoints.
# Usage: [GENERATIONS=N (default 50000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] [READINGS="OVERRIDE ..."]
#        launchers/readings.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=50000 SEEDS=16, the defaults) refreshes results/readings; any other
# budget, seed count or number-changing override writes to outputs/results/readings_g<N>_s<S>[,...] (see results_dir
# in _sweep.sh). It never writes to results/paper.
GENERATIONS="${GENERATIONS:-50000}"
OUT="${OUT:-outputs/readings}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
if [ -n "${READINGS:-}" ] && [ -z "${RESULTS:-}" ]; then   # a subset of the readings is never the committed study
    RESULTS="outputs/results/readings_g${GENERATIONS}_s${SEEDS},subset"
fi
results_dir readings 50000 16 "$@"
# READINGS (space-separated overrides) picks a subset of the alternative readings; the SPEC reading always runs.
read -r -a READINGS <<< "${READINGS:-env.reward=any_step env.reward=best_step env.reward=mean_step env.speed=clip \
env.poi_type=sign env.poi_type=value evaluation.fresh_ic=true mutation.sigma=0.316}"

duo() {  # duo READING_OVERRIDE...: k=1, k=2 and the homogeneous team under one reading
    sweep k=1,2 setup=duo "$@"
    sweep team=homogeneous setup=duo "$@"
}

duo "$@"                                      # the SPEC reading
for reading in "${READINGS[@]}"; do
    duo "$reading" "$@"
done
"$PYTHON" "$STUDIES"/readings/report.py export "$OUT" "$RESULTS"
mapfile -t lifting < <("$PYTHON" "$STUDIES"/readings/report.py lifting "$RESULTS")
echo "$(basename "$0"): readings that lift duo: ${lifting[*]:-none}" >&2
for reading in "${lifting[@]}"; do
    sweep k=1 setup=solo "$reading" "$@"
done
declare -A seen=()
combination=()
for reading in "${lifting[@]}"; do             # one value per key: the first lifting reading of each option
    key="${reading%%=*}"
    if [ -z "${seen[$key]:-}" ]; then
        seen[$key]=1
        combination+=("$reading")
    fi
done
if [ "${#combination[@]}" -gt 1 ]; then
    duo "${combination[@]}" "$@"
fi
"$PYTHON" "$STUDIES"/readings/report.py export "$OUT" "$RESULTS"
"$PYTHON" "$STUDIES"/readings/report.py report "$RESULTS"
