#!/usr/bin/env bash
# The coupling sweep (issue 55): every family of learner at coupling levels c = 1..6 (conf/setup/coupling<c>.yaml:
# every one of the 10 POIs needs c rovers at once and is worth 1, N = 2c rovers, the maximum team return 2 at every
# level), at one budget of agent-steps (budget.agent_steps), the fair contest's rules (docs/LEARNERS.md: the run's 16
# fixed starts, the best team kept: algorithm.final_team=best for the CCEA and the RL learners), SEEDS runs each,
# every final team also scored on its run's 256 held-out initial conditions; each job's summary.json records
# "coupling_level": c.
#   Learners: CC-(1+1)-ES k=1 and k=adaptive; the CCEA with D++; sep-CMA-ES over the team; PPO with parameter sharing
#             (stable-baselines3: the [rl] extra); MAPPO and IPPO (TorchRL: the [marl] extra). A learner whose extra
#             is not installed is skipped with a message.
# One job at a time (parallel=serial, record=off); after each, the compact results of every finished job of OUT go into
# RESULTS (python -m rovermarl.analysis export), then the coupling section of DOC. Resumable, also across machines and sessions: a job whose compact
# files are in RESULTS is skipped, one whose runs are in OUT resumes there from their checkpoints (the RL learners
# checkpoint every 25 iterations). Kill it at any time and launch it again: it goes on where it stopped.
# Usage: [AGENT_STEPS=N (default 19200000, the learners table's)] [SEEDS=S (default 5)] [OUT=DIR] [RESULTS=DIR]
#        [LEVELS="1 2 ..."] [LEARNERS="cces_k1 ..."] [PARALLEL="parallel=ray ray.num_cpus=2" (default parallel=serial)]
#        [DOC=docs/LEARNERS.md (the report so far: coupling section)]
#        launchers/coupling.sh [HYDRA_OVERRIDE ...]
# Only the study's budget (AGENT_STEPS=19200000 SEEDS=5) refreshes results/coupling; any other writes to
# outputs/results/coupling_g<AGENT_STEPS>_s<S>[,...] (results_dir in _sweep.sh).
AGENT_STEPS="${AGENT_STEPS:-19200000}"
SEEDS="${SEEDS:-5}"
GENERATIONS="$AGENT_STEPS"                     # what results_dir compares with the study's budget
OUT="${OUT:-outputs/coupling}"
LEVELS="${LEVELS:-1 2 3 4 5 6}"
DOC="${DOC:-docs/LEARNERS.md}"                 # where the report so far goes (a clean run: a copy outside the tree)
PARALLEL="${PARALLEL:-parallel=serial}"        # how a job's seeds run: one after another, or on Ray
LEARNERS="${LEARNERS:-cces_k1 cces_adaptive ccea_dpp cma ppo mappo ippo}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir coupling 19200000 5 "$@"

learner() {  # learner NAME: its overrides
    case "$1" in
        cces_k1) echo "k=1" ;;
        cces_adaptive) echo "k=adaptive" ;;
        ccea_dpp) echo "algorithm=ccea algorithm.reward=dpp +algorithm.final_team=best" ;;
        cma) echo "algorithm=cma" ;;
        ppo | mappo | ippo) echo "algorithm=$1 +algorithm.final_team=best checkpoint.every=25 parallel.chunk=25" ;;
        *) echo "$(basename "$0"): error: LEARNERS: no learner '$1'" >&2; exit 2 ;;
    esac
}

extra() {  # extra NAME: the modules a learner needs and its extra ("" when it needs none)
    case "$1" in
        ppo) echo "torch,stable_baselines3 rl" ;;
        mappo | ippo) echo "torch,torchrl marl" ;;
    esac
}

for c in $LEVELS; do
    case "$c" in
        [1-6]) ;;
        *) echo "$(basename "$0"): error: LEVELS: no coupling level '$c' (1..6)" >&2; exit 2 ;;
    esac
done
for c in $LEVELS; do
    for l in $LEARNERS; do
        read -ra lo <<< "$(learner "$l")"
        read -r modules ext <<< "$(extra "$l")"
        if [ -n "$modules" ] && ! "$PYTHON" -c "import $modules" 2>/dev/null; then
            echo "$(basename "$0"): coupling$c/$l: $modules not installed (pip install -e \".[$ext]\"): skipped" >&2
            continue
        fi
        read -ra par <<< "$PARALLEL"
        overrides=("setup=coupling$c" "${lo[@]}" "budget.agent_steps=$AGENT_STEPS" "record=off" "${par[@]}")
        name="$(job_name "${overrides[@]}" "seeds=$SEEDS")"
        if [ -f "$RESULTS/$name/summary.json" ] && [ -f "$RESULTS/$name/curves.npz" ]; then
            echo "$(basename "$0"): $name is in $RESULTS: skipped" >&2
            continue
        fi
        "$PYTHON" -m rovermarl.train -m "${overrides[@]}" "seeds=$SEEDS" "hydra.sweep.dir=$OUT" "$@"
        "$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --no-fig6 --trust-config
        "$PYTHON" "$STUDIES"/coupling/report.py "$RESULTS" --doc "$DOC" || true   # the report so far
    done
done
