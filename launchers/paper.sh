#!/usr/bin/env bash
# The whole reproduction study: Figs. 4, 5, 7 and 8 into OUT (resumable: rerun it after an interruption),
# then the compact results (RESULTS) and their figures and claim statistics.
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] launchers/paper.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (GENERATIONS=200000 SEEDS=16, the defaults) refreshes results/paper; any
# other budget, seed count or number-changing override writes to outputs/results/paper_g<N>_s<S>[,...]
# (see results_dir in _sweep.sh).
here="$(dirname "$0")"
# shellcheck source=launchers/_sweep.sh
source "$here/_sweep.sh"
results_dir paper 200000 16 "$@"
for fig in fig4 fig5 fig7 fig8; do
    bash "$here/$fig.sh" "$@"
done
"$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --generations "$GENERATIONS"
figures "$RESULTS" --format png --xscale log
"$PYTHON" "$STUDIES"/paper/report.py "$RESULTS"
