#!/usr/bin/env bash
# The baselines study (docs/BASELINES.md): CC-(1+1)-ES (k=1, k=2, adaptive) against the classic rover-domain CCEA
# with the global (G), difference (D) and D++ rewards, on solo, duo and trio, at an equal budget of team evaluations
# per run: EVALS for cc11es (one evaluation per generation), ceil((EVALS - 1) / (pop_size + 1)) generations of ccea
# (pop_size + 1 per generation). Then the compact results (RESULTS/baselines.json), the report
# (RESULTS/baselines.md) and the figures (RESULTS/figures, against team evaluations; FIGURES=no skips them).
# Resumable: rerun it after an interruption.
# Usage: [EVALS=N (default 400000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] [SETUPS="duo solo trio"]
#        launchers/baselines.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (EVALS=400000 SEEDS=16, all setups) refreshes results/baselines; any other
# writes to outputs/results/baselines_g<EVALS>_s<S>[,...] (results_dir in _sweep.sh).
EVALS="${EVALS:-400000}"
GENERATIONS="$EVALS"
OUT="${OUT:-outputs/baselines}"
POP=10                                        # conf/algorithm/ccea.yaml's pop_size
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
if [ -n "${SETUPS:-}" ] && [ -z "${RESULTS:-}" ]; then   # a subset of the setups is never the committed study
    RESULTS="outputs/results/baselines_g${EVALS}_s${SEEDS},${SETUPS// /_}"
fi
results_dir baselines 400000 16 "$@"
CCEA_GENERATIONS=$(( (EVALS - 1 + POP) / (POP + 1) ))
for setup in ${SETUPS:-duo solo trio}; do
    GENERATIONS="$EVALS" sweep k=1,2,adaptive "setup=$setup" "$@"
    GENERATIONS="$CCEA_GENERATIONS" sweep algorithm=ccea algorithm.reward=global,difference,dpp "setup=$setup" "$@"
done
"$PYTHON" -m rovermarl.analysis baselines export "$OUT" "$RESULTS"
"$PYTHON" -m rovermarl.analysis baselines report "$RESULTS"
figures "$OUT" --out "$RESULTS/figures" --format png --x evals   # score curves against team evaluations
