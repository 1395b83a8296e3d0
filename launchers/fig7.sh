#!/usr/bin/env bash
# Fig. 7: setup duo, fixed k = 1, 2, 4 with strict selection. The soft runs it is compared with are
# Fig. 5's (same OUT, same budget); they are not recomputed here.
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] launchers/fig7.sh [HYDRA_OVERRIDE ...]
source "$(dirname "$0")/_sweep.sh"
sweep k=1,2,4 setup=duo selection=strict "$@"
