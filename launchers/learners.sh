#!/usr/bin/env bash
# The learners study (issue 44, docs/LEARNERS.md): every coordination world x every family of learner at one budget
# of agent-steps (budget.agent_steps: a team evaluation is episodes x steps x rovers = 960 agent-steps for 4 rovers),
# SEEDS runs each, every final team also scored on its run's 256 held-out initial conditions.
#   Worlds:   solo, duo, trio (conf/setup), obstacles, random_pois (examples/), moving_pois once examples/moving_pois
#             exists (skipped until then).
#   Learners: CC-(1+1)-ES k=1, k=adaptive and homogeneous; the CCEA with D++; sep-CMA-ES over the team; PPO with
#             parameter sharing (stable-baselines3: pip install -e ".[rl]"; skipped without it); mappo and ippo
#             (TorchRL: pip install -e ".[marl]") run when named in LEARNERS (e.g. LEARNERS="mappo ippo"
#             WORLDS="solo duo trio"), not by default: the committed table has no column for them yet.
# One job at a time (parallel=serial, record=off); after each, the compact results of every finished job of OUT go into
# RESULTS (python -m rovermarl.analysis export), then docs/LEARNERS.md is regenerated (analysis learners).
# Resumable, also across machines and sessions: a job whose compact files are in RESULTS is skipped, one whose runs are
# in OUT resumes there from their checkpoints. Commit RESULTS between sessions and the study goes on where it stopped.
# Usage: [AGENT_STEPS=N (default 19200000)] [SEEDS=S (default 8)] [OUT=DIR] [RESULTS=DIR] [WORLDS="solo ..."]
#        [LEARNERS="cces_k1 ..."] [PARALLEL="parallel=ray ray.num_cpus=2" (default parallel=serial)]
#        launchers/learners.sh [HYDRA_OVERRIDE ...]
# Only the committed study's budget (AGENT_STEPS=19200000 SEEDS=8) refreshes results/learners; any other writes to
# outputs/results/learners_g<AGENT_STEPS>_s<S>[,...] (results_dir in _sweep.sh).
AGENT_STEPS="${AGENT_STEPS:-19200000}"
SEEDS="${SEEDS:-8}"
GENERATIONS="$AGENT_STEPS"                     # what results_dir compares with the committed study's budget
OUT="${OUT:-outputs/learners}"
WORLDS="${WORLDS:-solo duo trio obstacles random_pois moving_pois}"
PARALLEL="${PARALLEL:-parallel=serial}"        # how a job's seeds run: one after another, or on Ray
LEARNERS="${LEARNERS:-cces_k1 cces_adaptive cces_homogeneous ccea_dpp cma ppo}"
# shellcheck source=launchers/_sweep.sh
source "$(dirname "$0")/_sweep.sh"
results_dir learners 19200000 8 "$@"

world() {  # world NAME: its overrides (empty: not available here)
    case "$1" in
        solo | duo | trio) echo "setup=$1" ;;
        obstacles | random_pois | moving_pois)
            [ -d "examples/$1" ] && echo "env=$1 hydra.searchpath=[file://examples/$1]" ;;
        *) echo "$(basename "$0"): error: WORLDS: no world '$1'" >&2; exit 2 ;;
    esac
}

learner() {  # learner NAME: its overrides
    case "$1" in
        cces_k1) echo "k=1" ;;
        cces_adaptive) echo "k=adaptive" ;;
        cces_homogeneous) echo "team=homogeneous" ;;
        ccea_dpp) echo "algorithm=ccea algorithm.reward=dpp" ;;
        cma) echo "algorithm=cma" ;;
        ppo) echo "algorithm=ppo checkpoint.every=25 parallel.chunk=25" ;;   # a checkpoint every ~6 min
        mappo | ippo) echo "algorithm=$1 checkpoint.every=25 parallel.chunk=25" ;;   # TorchRL: the [marl] extra
        *) echo "$(basename "$0"): error: LEARNERS: no learner '$1'" >&2; exit 2 ;;
    esac
}


rl=yes
"$PYTHON" -c 'import torch, stable_baselines3' 2>/dev/null || rl=no
marl=yes
"$PYTHON" -c 'import torch, torchrl' 2>/dev/null || marl=no
for w in $WORLDS; do
    read -ra wo <<< "$(world "$w")"
    if [ "${#wo[@]}" -eq 0 ]; then
        echo "$(basename "$0"): world $w: examples/$w does not exist yet: skipped" >&2
        continue
    fi
    for l in $LEARNERS; do
        read -ra lo <<< "$(learner "$l")"
        if [ "$l" = ppo ] && [ "$rl" = no ]; then
            echo "$(basename "$0"): $w/ppo: torch and stable-baselines3 are not installed (pip install -e \".[rl]\"): skipped" >&2
            continue
        fi
        if { [ "$l" = mappo ] || [ "$l" = ippo ]; } && [ "$marl" = no ]; then
            echo "$(basename "$0"): $w/$l: torch and torchrl are not installed (pip install -e \".[marl]\"): skipped" >&2
            continue
        fi
        read -ra par <<< "$PARALLEL"
        overrides=("${wo[@]}" "${lo[@]}" "budget.agent_steps=$AGENT_STEPS" "record=off" "${par[@]}")
        name="$(job_name "${overrides[@]}" "seeds=$SEEDS")"
        if [ -f "$RESULTS/$name/summary.json" ] && [ -f "$RESULTS/$name/curves.npz" ]; then
            echo "$(basename "$0"): $name is in $RESULTS: skipped" >&2
            continue
        fi
        "$PYTHON" -m rovermarl.train -m "${overrides[@]}" "seeds=$SEEDS" "hydra.sweep.dir=$OUT" "$@"
        "$PYTHON" -m rovermarl.analysis export "$OUT" "$RESULTS" --no-fig6 --trust-config
        "$PYTHON" -m rovermarl.analysis learners "$RESULTS" || true   # the report so far (not yet: skipped)
    done
done
