# Shared by the figure launchers (sourced, not run). Budget and seed count come from the environment:
#   GENERATIONS (default 200000) and SEEDS (default 16); OUT is the sweep dir (default outputs/paper).
# Every job dir is OUT/<its overrides>, so a relaunch finds its finished runs and skips them, and
# unfinished runs resume from their checkpoints. Extra arguments are passed to every train command
# (Hydra overrides: ray.address=auto for a cluster, parallel=serial, ...).
set -euo pipefail
GENERATIONS="${GENERATIONS:-200000}"
SEEDS="${SEEDS:-16}"
OUT="${OUT:-outputs/paper}"
PYTHON="${PYTHON:-python}"

sweep() {  # sweep OVERRIDE... -- EXTRA...: one multirun into OUT
    "$PYTHON" -m rovermarl.train -m "$@" "generations=$GENERATIONS" "seeds=$SEEDS" "hydra.sweep.dir=$OUT"
}
