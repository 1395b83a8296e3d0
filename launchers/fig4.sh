#!/usr/bin/env bash
# Fig. 4: setup solo, fixed k = 1, 2, 4 and the homogeneous team.
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] launchers/fig4.sh [HYDRA_OVERRIDE ...]
source "$(dirname "$0")/_sweep.sh"
sweep k=1,2,4 setup=solo "$@"
sweep team=homogeneous setup=solo "$@"
