# shellcheck shell=bash
# Shared by the figure launchers (sourced, not run). Budget and seed count come from the environment:
#   GENERATIONS (default 200000) and SEEDS (default 16); OUT is the sweep dir (default outputs/paper);
#   FIGURES=no skips a study's figures (draw them later: python -m rovermarl.plot RESULTS_DIR).
# Every job dir is OUT/<its overrides>, so a relaunch finds its finished runs and skips them, and
# unfinished runs resume from their checkpoints. Extra arguments are passed to every train command
# (Hydra overrides: ray.address=auto for a cluster, parallel=serial, ...).
set -euo pipefail
GENERATIONS="${GENERATIONS:-200000}"
SEEDS="${SEEDS:-16}"
OUT="${OUT:-outputs/paper}"
PYTHON="${PYTHON:-python}"
STUDIES="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/studies"   # the studies' report scripts: STUDIES/<name>/report.py
FIGURES="${FIGURES:-yes}"

figures() {  # figures RESULTS_DIR PLOT_OPTION...: the study's figures into RESULTS_DIR/figures, unless FIGURES=no
    if [ "$FIGURES" != no ]; then   # (plot draws exported results elsewhere unless told: here the study asks)
        "$PYTHON" -m rovermarl.plot "$@" --out "$1/figures"
    fi
}

sweep() {  # sweep OVERRIDE... -- EXTRA...: one multirun into OUT
    "$PYTHON" -m rovermarl.train -m "$@" "generations=$GENERATIONS" "seeds=$SEEDS" "hydra.sweep.dir=$OUT"
}

job_name() {  # job_name OVERRIDE...: the job's dir name under OUT (and RESULTS), as rovermarl.train names it (values
    "$PYTHON" -c 'import sys; from rovermarl.config import job_dirs, quote_numeric_options   # parsed: true -> True)
print(job_dirs(quote_numeric_options(sys.argv[1:]), True, ".")[0].name)' "$@"
}

compact_job() {  # compact_job OVERRIDE...: one job of a resumable study, skipped if its compact files are in
    local name   # RESULTS; else run (resuming in OUT), then export every finished job of OUT into RESULTS
    name="$(job_name "$@" "generations=$GENERATIONS")"
    if [ -f "$RESULTS/$name/summary.json" ] && [ -f "$RESULTS/$name/curves.npz" ]; then
        echo "$(basename "$0"): $name is in $RESULTS: skipped" >&2
        return
    fi
    sweep "$@"
    "$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --generations "$GENERATIONS" --no-fig6
}

# results_dir NAME STUDY_GENERATIONS STUDY_SEEDS [HYDRA_OVERRIDE ...]: sets RESULTS, where the compact results,
# figures and report of a study launcher go. The committed study (GENERATIONS and SEEDS equal to its budget, no
# extra override that changes the numbers) refreshes results/NAME, which is committed data. Any other run goes
# to outputs/results/NAME_g<GENERATIONS>_s<SEEDS>[,<overrides>] (outputs/ is not tracked). An explicit RESULTS
# is used as given, except that a run other than the committed study stops (exit 2, before any work) if RESULTS
# holds tracked files: tracked results are only ever rewritten by the committed study.
results_dir() {
    local name="$1" study_generations="$2" study_seeds="$3" arg
    shift 3
    local extra=()
    for arg in "$@"; do
        case "$arg" in   # settings that cannot change the numbers (as in the job dir names), and Hydra's own
            parallel=* | parallel.* | ray.* | record=* | record.* | checkpoint.* | resume=* | hydra.* | [~+]hydra.*) ;;
            *) extra+=("$arg") ;;
        esac
    done
    local study=no
    if [ "$GENERATIONS" = "$study_generations" ] && [ "$SEEDS" = "$study_seeds" ] && [ "${#extra[@]}" -eq 0 ]; then
        study=yes
    fi
    if [ -z "${RESULTS:-}" ]; then
        if [ "$study" = yes ]; then
            RESULTS="results/$name"
        else
            local tag="${name}_g${GENERATIONS}_s${SEEDS}"
            if [ "${#extra[@]}" -gt 0 ]; then
                tag="$tag,$(IFS=,; echo "${extra[*]}" | tr '/' '_')"
            fi
            RESULTS="outputs/results/$tag"
        fi
    elif [ "$study" = no ] && [ -d "$RESULTS" ] && [ -n "$(git -C "$RESULTS" ls-files -- . 2>/dev/null | head -n 1)" ]; then
        echo "$(basename "$0"): error: RESULTS=$RESULTS holds committed results, and GENERATIONS=$GENERATIONS" \
             "SEEDS=$SEEDS${extra[*]:+ ${extra[*]}} is not the committed study (GENERATIONS=$study_generations" \
             "SEEDS=$study_seeds); unset RESULTS (default: outputs/results/...) or choose an untracked dir" >&2
        exit 2
    fi
    echo "$(basename "$0"): GENERATIONS=$GENERATIONS SEEDS=$SEEDS: sweep into $OUT, results into $RESULTS" >&2
}
