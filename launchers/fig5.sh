#!/usr/bin/env bash
# Fig. 5: setup duo, fixed k = 1, 2, 4 and the homogeneous team (soft selection).
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] launchers/fig5.sh [HYDRA_OVERRIDE ...]
source "$(dirname "$0")/_sweep.sh"
sweep k=1,2,4 setup=duo "$@"
sweep team=homogeneous setup=duo "$@"
