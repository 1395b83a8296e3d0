#!/usr/bin/env bash
# The baselines study (docs/BASELINES.md): CC-(1+1)-ES (k=1, k=2, adaptive) against the classic rover-domain CCEA
# with the global (G), difference (D) and D++ rewards, on solo, duo and trio, at an equal budget of team evaluations
# per run: EVALS for cc11es (one evaluation per generation), ceil((EVALS - 1) / (pop_size + 1)) generations of ccea
# (pop_size + 1 per generation). One job at a time; after each, its compact results join RESULTS/baselines.json,
# then the report (RESULTS/baselines.md) and the figures (RESULTS/figures, against team evaluations, from the compact
# curves; FIGURES=no skips them).
# Resumable, also across machines and sessions: a job already in RESULTS/baselines.json is skipped, one whose runs
# are in OUT resumes there. Commit RESULTS between sessions and the study goes on where it stopped.
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
# Each job: its overrides | its method as the analysis labels it (studies/baselines/report.py: METHODS).
JOBS=("k=1|k=1" "k=2|k=2" "k=adaptive|adaptive" "algorithm=ccea algorithm.reward=global|ccea G"
      "algorithm=ccea algorithm.reward=difference|ccea D" "algorithm=ccea algorithm.reward=dpp|ccea D++")
DONE="$("$PYTHON" "$STUDIES"/baselines/report.py done "$RESULTS")"
for setup in ${SETUPS:-duo solo trio}; do
    for job in "${JOBS[@]}"; do
        if grep -qxF "$setup ${job#*|}" <<< "$DONE"; then
            echo "$(basename "$0"): ${job#*|} on $setup is in $RESULTS/baselines.json: skipped" >&2
            continue
        fi
        read -ra overrides <<< "${job%%|*}"
        budget="$EVALS"
        [ "${overrides[0]}" = algorithm=ccea ] && budget="$CCEA_GENERATIONS"
        GENERATIONS="$budget" sweep "${overrides[@]}" "setup=$setup" "$@"
        "$PYTHON" "$STUDIES"/baselines/report.py export "$OUT" "$RESULTS"
    done
done
"$PYTHON" "$STUDIES"/baselines/report.py report "$RESULTS"
if [ "$FIGURES" != no ]; then
    "$PYTHON" "$STUDIES"/baselines/report.py figures "$RESULTS"
fi
