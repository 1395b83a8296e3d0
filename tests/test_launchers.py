"""Study launchers never write into committed results: a run at another budget exports into outputs/results/.

The launcher runs in a temporary git clone of this checkout whose working tree (tracked and untracked, not ignored
files, as they are now) is committed there, so the clone starts clean and `git status` shows what the run changed.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GIT = ["git", "-c", "user.name=rovermarl tests", "-c", "user.email=tests@rovermarl.invalid", "-c", "gc.auto=0"]

pytestmark = pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(),
                                reason="needs git and a git checkout")


def git(*args: str, cwd: Path) -> str:
    return subprocess.run([*GIT, *args], cwd=cwd, check=True, capture_output=True, text=True).stdout


def snapshot_clone(dest: Path) -> Path:
    """``git clone`` of ROOT, with ROOT's current working tree committed in the clone (so it starts clean)."""
    git("clone", "--quiet", "--no-hardlinks", str(ROOT), str(dest), cwd=ROOT)
    files = git("ls-files", "-z", "--cached", "--others", "--exclude-standard", cwd=ROOT).split("\0")
    files = {f for f in files if f and (ROOT / f).is_file()}
    for f in set(git("ls-files", "-z", cwd=dest).split("\0")) - files - {""}:
        (dest / f).unlink()
    for f in files:
        (dest / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, dest / f)
    git("add", "--all", cwd=dest)
    git("commit", "--quiet", "--allow-empty", "-m", "working tree snapshot", cwd=dest)
    assert git("status", "--porcelain", cwd=dest) == ""
    return dest


def launch(clone: Path, script: str, *overrides: str, **env: str) -> subprocess.CompletedProcess:
    inherited = {k: v for k, v in os.environ.items() if k not in ("GENERATIONS", "SEEDS", "OUT", "RESULTS")}
    full_env = {**inherited, "PYTHON": sys.executable, **env}
    return subprocess.run(["bash", f"launchers/{script}", *overrides], cwd=clone, env=full_env,
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def clone(tmp_path_factory) -> Path:
    return snapshot_clone(tmp_path_factory.mktemp("launchers") / "clone")


# Stands in for Python in the fast test: records each command and writes where the real one writes (the train
# runs into hydra.sweep.dir, export into its second argument, plot into RESULTS/figures, the claims into RESULTS).
FAKE_PYTHON = r"""#!/usr/bin/env bash
set -eu
echo "$*" >> "$LAUNCH_LOG"
case "$1" in */studies/paper/report.py) echo claims > "$2/claims.md" ;; esac
case "$2" in
    rovermarl.train) for a in "$@"; do case "$a" in hydra.sweep.dir=*) mkdir -p "${a#*=}/figures" ;; esac; done ;;
    rovermarl.analysis) mkdir -p "$5" && echo {} > "$5/compute.json" ;;
    rovermarl.plot) mkdir -p "$3/figures" && echo png > "$3/figures/curves_solo.png" ;;
esac
"""


def test_a_small_paper_study_writes_only_into_its_budget_dir(clone, tmp_path):
    """Fast: the launchers' own logic, with a stand-in for Python (the real pipeline: the slow test below)."""
    fake = tmp_path / "python"
    fake.write_text(FAKE_PYTHON)
    fake.chmod(0o755)
    log = tmp_path / "launch.log"
    proc = launch(clone, "paper.sh", "parallel=serial", GENERATIONS="200", SEEDS="2", PYTHON=str(fake),
                  LAUNCH_LOG=str(log))
    assert proc.returncode == 0, proc.stderr
    assert git("status", "--porcelain", "--untracked-files=all", cwd=clone) == ""
    results = "outputs/results/paper_g200_s2"
    commands = log.read_text().splitlines()
    assert len(commands) == 9                                      # 6 sweeps, export, plot, claims
    assert all(c.endswith("generations=200 seeds=2 hydra.sweep.dir=outputs/paper") for c in commands[:6])
    assert commands[6:] == [f"-m rovermarl.analysis export outputs/paper {results} --generations 200",
                            f"-m rovermarl.plot {results} --format png --xscale log --out {results}/figures",
                            f"{clone}/studies/paper/report.py {results}"]
    assert (clone / results / "claims.md").is_file() and (clone / results / "figures" / "curves_solo.png").is_file()


def test_the_heldout_launcher_stops_when_its_done_check_fails(tmp_path):
    """A failing ``done`` (a crash exits 1) is no "not done" (3): the launcher stops, nothing is recomputed."""
    (tmp_path / "results" / "job").mkdir(parents=True)
    (tmp_path / "results" / "job" / "summary.json").write_text("{}")
    fake, log = tmp_path / "python", tmp_path / "launch.log"
    fake.write_text('#!/usr/bin/env bash\necho "$*" >> "$LAUNCH_LOG"\n'
                    'case "$1" in */studies/heldout/report.py) echo Traceback >&2; exit 1 ;; esac\n')
    fake.chmod(0o755)
    proc = subprocess.run(["bash", str(ROOT / "launchers" / "heldout.sh")], cwd=tmp_path, capture_output=True,
                          text=True, env={**os.environ, "PYTHON": str(fake), "RESULTS": "results",
                                          "LAUNCH_LOG": str(log)}, timeout=60)
    assert proc.returncode == 1 and "done failed (exit 1, above): stopped" in proc.stderr, proc.stderr
    assert log.read_text().splitlines() == [f"{ROOT}/studies/heldout/report.py done results/job"]


def test_the_learners_launcher_stops_on_an_unreadable_summary_and_skips_a_clean_job(tmp_path):
    """The learners' done check: a clean job is skipped, a job without its files runs, and a summary.json it cannot
    read stops the launcher in one line (before, any failure read as "not done" and the job ran again)."""
    results = tmp_path / "results"
    log = tmp_path / "launch.log"
    wrapper = tmp_path / "python"                # the real Python for the check, a logged stand-in for the rest
    wrapper.write_text(f'#!/usr/bin/env bash\nif [ "$1" = -c ]; then exec {sys.executable} "$@"; fi\n'
                       'echo "$*" >> "$LAUNCH_LOG"\n')
    wrapper.chmod(0o755)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHON": str(wrapper), "RESULTS": str(results),
           "LAUNCH_LOG": str(log), "LEARNERS": "cces_k1", "WORLDS": "solo", "REGIMES": "fixed", "SEEDS": "2",
           "AGENT_STEPS": "960", "DOC": str(tmp_path / "doc.md")}

    def run():
        return subprocess.run(["bash", str(ROOT / "launchers" / "learners.sh")], cwd=ROOT, capture_output=True,
                              text=True, env=env, timeout=120)

    proc = run()                                 # nothing there: the job runs, then export and the report
    assert proc.returncode == 0, proc.stderr
    assert "-m rovermarl.train -m setup=solo k=1" in log.read_text()
    name = subprocess.run([sys.executable, "-c", "import sys; from rovermarl.config import job_dirs, "
                           "quote_numeric_options; print(job_dirs(quote_numeric_options(sys.argv[1:]), True, '.')"
                           "[0].name)", "setup=solo", "k=1", "budget.agent_steps=960", "record=off",
                           "parallel=serial", "seeds=2"], capture_output=True, text=True, check=True, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}).stdout.strip()
    (results / name).mkdir(parents=True)
    (results / name / "curves.npz").write_bytes(b"")
    (results / name / "summary.json").write_text('{"train_ic": "fixed", "provenance": {"dirty": false}}')
    log.unlink(missing_ok=True)
    proc = run()                                 # clean: skipped
    assert proc.returncode == 0 and "(clean, regime recorded): skipped" in proc.stderr, proc.stderr
    assert not log.exists()                      # no command but the check
    (results / name / "summary.json").write_text('{"train_ic": ')
    log.unlink(missing_ok=True)
    proc = run()                                 # unreadable: stopped, nothing recomputed
    assert proc.returncode == 1, proc.stderr
    assert "the done check failed (exit 1, above): stopped" in proc.stderr and "Traceback" not in proc.stderr
    assert not log.exists()


@pytest.mark.skipif(os.environ.get("ROVERMARL_SLOW_LAUNCHER_TEST") != "1",
                    reason="the real small study takes minutes: set ROVERMARL_SLOW_LAUNCHER_TEST=1")
def test_a_real_small_paper_study_leaves_the_committed_results_alone(tmp_path):
    clone = snapshot_clone(tmp_path / "clone")
    proc = launch(clone, "paper.sh", "parallel=serial", GENERATIONS="200", SEEDS="2")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert git("status", "--porcelain", "--untracked-files=all", cwd=clone) == ""   # nothing modified or added
    results = clone / "outputs" / "results" / "paper_g200_s2"
    assert (results / "claims.md").is_file() and (results / "compute.json").is_file()
    assert any((results / "figures").glob("*.png"))


@pytest.mark.parametrize("script, study", [("paper.sh", "paper"), ("selectors.sh", "selectors")])
def test_an_explicit_tracked_results_dir_is_refused_for_another_budget(clone, script, study):
    proc = launch(clone, script, GENERATIONS="100", SEEDS="2", RESULTS=f"results/{study}", PYTHON="false")
    assert proc.returncode == 2
    assert f"RESULTS=results/{study} holds committed results" in proc.stderr
    assert git("status", "--porcelain", "--untracked-files=all", cwd=clone) == ""


@pytest.mark.parametrize("script, env, overrides, expected", [
    ("paper.sh", {}, (), "results/paper"),
    ("paper.sh", {"GENERATIONS": "200000", "SEEDS": "16"}, ("ray.address=auto", "parallel.workers=8"),
     "results/paper"),
    ("paper.sh", {"GENERATIONS": "2000", "SEEDS": "4"}, (), "outputs/results/paper_g2000_s4"),
    ("paper.sh", {"SEEDS": "8"}, (), "outputs/results/paper_g200000_s8"),
    ("paper.sh", {}, ("mutation.sigma=0.05",), "outputs/results/paper_g200000_s16,mutation.sigma=0.05"),
    ("selectors.sh", {}, (), "results/selectors"),
    ("selectors.sh", {"GENERATIONS": "200000"}, (), "outputs/results/selectors_g200000_s16"),
])
def test_where_the_results_go(clone, script, env, overrides, expected):
    # PYTHON=false stops the launcher at its first command, after it has announced where the results go
    proc = launch(clone, script, *overrides, PYTHON="false", **env)
    assert f"results into {expected}\n" in proc.stderr, proc.stderr


def test_job_name_is_the_dir_train_makes_for_parsed_values():
    """A launcher skips a job by its dir name: booleans and quoted numbers are named as Hydra parses them
    (evaluation.fresh_ic=true -> True), or the launcher relaunches a finished job every time."""
    from rovermarl.config import job_dirs, quote_numeric_options
    argv = ["setup=solo", "k=1", "evaluation.fresh_ic=true", "budget.agent_steps=960000", "record=off", "seeds=2"]
    out = subprocess.run(["bash", "-c", 'source launchers/_sweep.sh; job_name "$@"', "_", *argv], cwd=ROOT,
                         capture_output=True, text=True, env={**os.environ, "PYTHON": sys.executable}, check=True)
    assert out.stdout.strip() == job_dirs(quote_numeric_options(argv), True, ".")[0].name
    assert out.stdout.strip() == "budget.agent_steps=960000,evaluation.fresh_ic=True,k=1,setup=solo"
