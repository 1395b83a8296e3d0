#!/usr/bin/env bash
# The paper's sweeps on both setups: fixed k = 1, 2, 4 and EXP3-adaptive k (Figs. 4, 5, 8), then the
# homogeneous control. Extra arguments are Hydra overrides, e.g. `launchers/paper.sh generations=20000`.
set -euo pipefail
python -m rovermarl.train -m k=1,2,4,adaptive setup=solo,duo "$@"
python -m rovermarl.train -m team=homogeneous setup=solo,duo "$@"
