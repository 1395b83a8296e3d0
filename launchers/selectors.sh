#!/usr/bin/env bash
# The k-selector benchmark: every selector (the paper's EXP3 `adaptive`, UCB1, Thompson sampling,
# epsilon-greedy, EXP3.S, the N-to-1 schedule), every fixed k and the homogeneous team, on setups solo,
# duo and trio; then the compact results, figures and the comparison table (docs/SELECTORS.md quotes it).
# Usage: [GENERATIONS=N (default 50000)] [SEEDS=S] [OUT=DIR] [RESULTS=DIR] launchers/selectors.sh [HYDRA_OVERRIDE ...]
# Only the committed benchmark's budget (GENERATIONS=50000 SEEDS=16, the defaults) refreshes results/selectors;
# any other budget, seed count or number-changing override writes to outputs/results/selectors_g<N>_s<S>[,...]
# (see results_dir in _sweep.sh).
GENERATIONS="${GENERATIONS:-50000}"
OUT="${OUT:-outputs/selectors}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir selectors 50000 16 "$@"
sweep k=1,2,3,4,adaptive,ucb1,thompson,egreedy,exp3s,schedule setup=solo,duo,trio "$@"
sweep team=homogeneous setup=solo,duo,trio "$@"
"$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --generations "$GENERATIONS" --no-fig6
figures "$RESULTS" --format png --xscale log
"$PYTHON" -m rovermarl.analysis selectors "$RESULTS"
