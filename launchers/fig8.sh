#!/usr/bin/env bash
# Fig. 8: both setups with EXP3-adaptive k (the fixed-k references are Figs. 4 and 5's runs).
# Usage: [GENERATIONS=N] [SEEDS=S] [OUT=DIR] launchers/fig8.sh [HYDRA_OVERRIDE ...]
source "$(dirname "$0")/_sweep.sh"
sweep k=adaptive setup=solo,duo "$@"
