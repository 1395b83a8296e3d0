#!/usr/bin/env bash
# The whole reproduction study: Figs. 4, 5, 7 and 8 into OUT (resumable: rerun it after an interruption),
# then the compact results (RESULTS, default results/paper) and their figures and claim statistics.
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] launchers/paper.sh [HYDRA_OVERRIDE ...]
here="$(dirname "$0")"
source "$here/_sweep.sh"
RESULTS="${RESULTS:-results/paper}"
for fig in fig4 fig5 fig7 fig8; do
    bash "$here/$fig.sh" "$@"
done
"$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --generations "$GENERATIONS"
"$PYTHON" -m rovermarl.plot "$RESULTS" --format png --xscale log
"$PYTHON" -m rovermarl.analysis claims "$RESULTS"
