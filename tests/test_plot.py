"""Figures: ``python -m rovermarl.plot`` on synthetic and real sweeps, quartile lines, bad input, the callback."""

import json
import logging

import numpy as np
import pytest
from omegaconf import OmegaConf

from rovermarl import make_world
from rovermarl.analysis import draw, figures
from rovermarl.analysis.curve_figures import fig_curves, quartile_generations
from rovermarl.analysis.draw import MAX_POINTS
from rovermarl.analysis.sweep import find_jobs, labels
from rovermarl.plot import PlotCallback, main
from tests.conftest import run_cli


def curve(n_gen: int, reach: int | None, level: float = 5.0, noise: bool = False, seed: int = 0) -> np.ndarray:
    """A score curve (n_gen + 1,) below ``level`` until generation ``reach`` (None: never), then at ``level``."""
    rng = np.random.default_rng(seed)
    score = rng.uniform(0, level - 1, n_gen + 1) if noise else np.linspace(0, level - 1, n_gen + 1)
    if reach is not None:
        score[reach:] = level
    return score


def make_job(sweep, name, curves, *, setup="duo", k="1", team="heterogeneous", selection="soft", probs=False,
             finished=True, overrides=()):
    """A job dir like ``rovermarl.train -m`` writes, with the given score curves (one run each)."""
    job = sweep / name
    (job / ".hydra").mkdir(parents=True)
    k_cfg = ({"_target_": "rovermarl.evolution.selectors.EXP3", "gamma": 0.1, "arms": None} if not k.isdigit() else
             {"_target_": "rovermarl.evolution.selectors.FixedK", "value": int(k)})
    config = {"setup": {"name": setup}, "k": k_cfg, "selection": {"strict": selection == "strict"},
              "team": {"_target_": f"rovermarl.evolution.team.{team.capitalize()}Team"}, "seeds": len(curves)}
    (job / ".hydra" / "config.yaml").write_text(json.dumps(config))
    (job / ".hydra" / "overrides.yaml").write_text(json.dumps([f"k={k}", f"setup={setup}", f"team={team}",
                                                               f"selection={selection}", *overrides]))
    choices = {"setup": setup, "k": k, "team": team, "selection": selection}
    for seed, score in enumerate(curves):
        run = job / "runs" / f"seed_{seed:03d}"
        run.mkdir(parents=True)
        n = len(score) - 1
        extra = {"probs": np.full((n, 4), 0.25)} if probs else {}
        np.savez(run / "curve.npz", score=score, k=np.ones(n, np.int64), accepted=np.ones(n, bool),
                 child_score=score[1:], **extra)
    if finished:
        (job / "summary.json").write_text(json.dumps({"choices": choices, "seeds": list(range(len(curves)))}))
    return job


def add_behaviour(run, setup="duo", gens=(0, 7, 19), seed=0):
    """behaviour.npz and occupancy.npz from real rollouts of random teams (one new rover policy per entry)."""
    world = make_world(setup)
    rng = np.random.default_rng(seed)
    ic = world.initial_conditions(seed)
    genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
    xy, counts = [], []
    for _ in gens:
        traj = world.rollout(genomes, ic)
        xy.append(traj.xy.astype(np.float32))
        dist = np.linalg.norm(traj.xy[:, -1, :, None] - world.poi_xy, axis=-1)  # (E, N, P)
        counts.append((dist <= world.obs_radius).sum(axis=1).astype(np.int8))
        genomes[rng.integers(world.n_rovers)] = rng.uniform(-2, 2, world.n_params)
    gens = np.array(gens, dtype=np.int64)
    np.savez(run / "behaviour.npz", generation=gens, score=np.arange(len(gens), dtype=float), xy=np.stack(xy))
    np.savez(run / "occupancy.npz", generation=gens, count=np.stack(counts))


def by_name(index):
    return {f["name"]: f for f in index["figures"]}


@pytest.fixture
def paper_sweep(tmp_path):
    """Setup duo with k=1, 2, 4, homogeneous and adaptive; setup solo with k=1 and 2 (3 runs each, 60 gens)."""
    sweep = tmp_path / "sweep"
    for k, team in (("1", "heterogeneous"), ("2", "heterogeneous"), ("4", "heterogeneous"), ("1", "homogeneous"),
                    ("adaptive", "heterogeneous")):
        make_job(sweep, f"k={k},setup=duo,team={team}", [curve(60, r) for r in (10, 30, None)], k=k, team=team,
                 probs=k == "adaptive")
    for k in ("1", "2"):
        make_job(sweep, f"k={k},setup=solo", [curve(60, r, 4) for r in (5, 50, None)], k=k, setup="solo")
    return sweep


def test_figures_and_panels_match_methods(paper_sweep, capsys):
    main([str(paper_sweep)])
    assert capsys.readouterr().out.startswith("rovermarl.plot: 3 figures (6 files) in ")
    index = json.loads((paper_sweep / "figures" / "index.json").read_text())
    figs = by_name(index)
    assert set(figs) == {"curves_duo", "curves_solo", "bandit_duo"}
    for f in index["figures"]:
        assert f["files"] == [f"{f['name']}.png", f"{f['name']}.pdf"]
        for name in f["files"]:
            assert (paper_sweep / "figures" / name).stat().st_size > 1000
    assert figs["curves_duo"]["methods"] == ["k=1", "k=2", "k=4", "homogeneous", "adaptive"]
    assert figs["curves_solo"]["methods"] == ["k=1", "k=2"]
    for name in ("curves_duo", "curves_solo"):
        assert figs[name]["axes"] == figs[name]["panels"] == 1 + len(figs[name]["methods"])
    assert figs["bandit_duo"]["methods"] == ["adaptive"] and figs["bandit_duo"]["axes"] == 1
    # 3 runs reaching at 10, 30, never: 1/4 -> 1st run, 1/2 -> 2nd, 3/4 -> 3rd (never)
    assert figs["curves_duo"]["quartile_generations"]["k=1"] == [10, 30, None]
    assert figs["curves_solo"]["threshold"] == 4 and figs["curves_solo"]["quartile_generations"]["k=2"] == [5, 50, None]
    assert any("behaviour.npz" in n for n in index["notes"]) and any("occupancy.npz" in n for n in index["notes"])
    assert not list((paper_sweep / "figures").glob("*.tmp"))


def test_quartile_lines_on_full_data_with_downsampled_lines(tmp_path):
    reach = [12345, 7, 20001, 300, None, 15000, 9999, None]  # sorted: 7, 300, 9999, 12345, 15000, 20001
    make_job(tmp_path, "k=2,setup=duo", [curve(25_000, r, noise=True, seed=i) for i, r in enumerate(reach)], k="2")
    assert quartile_generations([curve(25_000, r) for r in reach], 5.0) == [300, 12345, 20001]
    jobs, _ = find_jobs(tmp_path)
    fig, info = fig_curves("duo", jobs, 5.0)
    assert info["quartile_generations"] == {"k=2": [300, 12345, 20001]}
    runs_ax = fig.axes[1]
    dotted = [(line.get_xdata()[0], line.get_linewidth()) for line in runs_ax.lines if line.get_linestyle() == ":"]
    assert dotted == [(300, 0.8), (12345, 2.0), (20001, 0.8)]
    assert all(len(line.get_xdata()) <= MAX_POINTS for ax in fig.axes for line in ax.lines)
    # a custom threshold from the command line moves the lines
    main([str(tmp_path), "--threshold", "duo=4.5", "--format", "png"])
    index = json.loads((tmp_path / "figures" / "index.json").read_text())
    assert by_name(index)["curves_duo"]["threshold"] == 4.5
    assert not (tmp_path / "figures" / "curves_duo.pdf").exists()


def test_downsample_is_exact_for_step_curves():
    score = np.zeros(30_001)
    score[[100, 20_000, 29_000]] = 1
    score = np.cumsum(score)
    x, y = draw.downsample(score)
    assert len(x) <= 10 and x[-1] == 30_000
    np.testing.assert_array_equal(np.interp(np.arange(30_001), x, y), score)


def test_soft_vs_strict_and_unique_labels(tmp_path):
    for k in ("1", "2"):
        for sel in ("soft", "strict"):
            make_job(tmp_path, f"k={k},selection={sel}", [curve(40, 20), curve(40, None)], k=k, selection=sel)
    for gamma in ("0.1", "0.5"):
        make_job(tmp_path, f"k=adaptive,k.gamma={gamma}", [curve(40, 30)], k="adaptive", probs=True,
                 overrides=[f"k.gamma={gamma}", "parallel=serial"])
    index = figures.plot_sweep(tmp_path, formats=["png"])
    figs = by_name(index)
    # strict runs with a soft counterpart are drawn in soft_vs_strict only
    assert figs["curves_duo"]["methods"] == ["k=1", "k=2", "adaptive (k.gamma=0.1)", "adaptive (k.gamma=0.5)"]
    assert figs["soft_vs_strict_duo"]["methods"] == ["k=1", "k=1 strict", "k=2", "k=2 strict"]
    assert figs["soft_vs_strict_duo"]["axes"] == 1 + 2
    assert figs["bandit_duo"]["axes"] == 2
    jobs, _ = find_jobs(tmp_path)
    assert labels([j for j in jobs if not j.strict and not j.bandit]) == ["k=1", "k=2"]  # no suffix when unmixed


def test_partial_sweep_is_plotted_with_notes(tmp_path):
    make_job(tmp_path, "k=1,setup=duo", [curve(50, 10), curve(50, 20)])
    make_job(tmp_path, "k=2,setup=duo", [curve(50, 5)], k="2", finished=False)  # running: no summary.json yet
    (tmp_path / "k=4,setup=duo" / ".hydra").mkdir(parents=True)  # not started
    (tmp_path / "k=4,setup=duo" / "summary.json").write_text("{}")
    index = figures.plot_sweep(tmp_path, formats=["png"])
    assert by_name(index)["curves_duo"]["methods"] == ["k=1", "k=2"]
    assert [j["finished"] for j in index["jobs"]] == [True, False]
    assert any("k=2,setup=duo: unfinished" in n for n in index["notes"])
    assert any("k=4,setup=duo: no finished run" in n for n in index["notes"])


def test_update_and_occupancy_figures(tmp_path):
    job = make_job(tmp_path, "k=1,setup=duo", [curve(20, 8), curve(20, 3)])
    add_behaviour(job / "runs" / "seed_001", gens=(0, 4, 9, 20))
    index = figures.plot_sweep(tmp_path, formats=["png"])
    figs = by_name(index)
    update = figs["update_duo"]
    assert update["generations"] == [9, 20]                                      # the last rise: the final team
    assert update["axes"] == 2 * len(update["episodes"]) == 8 and update["run"].endswith("seed_001")
    assert figs["occupancy_duo"]["panels"] == 3 and figs["occupancy_duo"]["entries"] == 4
    # an explicit run and generation
    main([str(tmp_path), "--format", "png", "--update-run", str(job / "runs" / "seed_001"), "--update-gen", "4"])
    index = json.loads((tmp_path / "figures" / "index.json").read_text())
    assert by_name(index)["update_duo"]["generations"] == [0, 4] and by_name(index)["update_duo"]["scores"] == [0, 1]


def _error_line(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rovermarl.plot: error: "), err
    return err


def test_bad_input_exits_2_with_one_line(tmp_path, capsys):
    assert "no such directory" in _error_line(capsys, [str(tmp_path / "missing")])
    (tmp_path / "file.txt").write_text("x")
    assert "not a directory" in _error_line(capsys, [str(tmp_path / "file.txt")])
    (tmp_path / "empty").mkdir()
    assert "empty directory" in _error_line(capsys, [str(tmp_path / "empty")])
    (tmp_path / "other" / "sub").mkdir(parents=True)
    (tmp_path / "other" / "sub" / "notes.txt").write_text("x")
    assert "no job under" in _error_line(capsys, [str(tmp_path / "other")])
    (tmp_path / "bare" / "runs" / "seed_000").mkdir(parents=True)
    (tmp_path / "bare" / "runs" / "seed_000" / "curve.npz").write_bytes(b"not a zip")
    assert "no readable run" in _error_line(capsys, [str(tmp_path / "bare")])
    assert "--threshold" in _error_line(capsys, [str(tmp_path), "--threshold", "duo=high"])
    make_job(tmp_path / "ok", "k=1", [curve(10, 3)])
    assert "no behaviour.npz" in _error_line(capsys, [str(tmp_path / "ok"), "--update-run",
                                                      str(tmp_path / "ok" / "k=1" / "runs" / "seed_000")])


def test_cli_bad_path_subprocess(tmp_path):
    proc = run_cli(str(tmp_path / "nope"), module="rovermarl.plot", cwd=tmp_path, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines() == [f"rovermarl.plot: error: no such directory: {tmp_path / 'nope'}"]


def test_callback_never_raises(tmp_path, paper_sweep, caplog):
    callback = PlotCallback(formats=["png"])
    with caplog.at_level(logging.WARNING, logger="rovermarl.plot"):
        callback.on_multirun_end(OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path / "nothing")}}}))
        callback.on_multirun_end(OmegaConf.create({}))
    assert len([r for r in caplog.records if r.levelno == logging.WARNING]) == 2
    callback.on_multirun_end(OmegaConf.create({"hydra": {"sweep": {"dir": str(paper_sweep)},
                                                         "overrides": {"task": ["k=1,2", "setup=solo"]}}}))
    assert (paper_sweep / "figures" / "curves_solo.png").exists()          # only the launch's own jobs are read
    index = json.loads((paper_sweep / "figures" / "index.json").read_text())
    assert sorted(j["dir"] for j in index["jobs"]) == ["k=1,setup=solo", "k=2,setup=solo"]


def test_real_tiny_sweep_with_callback(tmp_path):
    sweep = tmp_path / "sweep"
    proc = run_cli("-m", "k=1,adaptive", "setup=duo", "generations=25", "seeds=2", "parallel=serial",
                   f"hydra.sweep.dir={sweep}",
                   cwd=tmp_path, timeout=240)
    assert proc.returncode == 0, proc.stderr[-3000:]
    index = json.loads((sweep / "figures" / "index.json").read_text())
    figs = by_name(index)
    assert figs["curves_duo"]["methods"] == ["k=1", "adaptive"] and figs["curves_duo"]["axes"] == 3
    assert figs["bandit_duo"]["axes"] == 1
    for f in index["figures"]:
        assert all((sweep / "figures" / name).exists() for name in f["files"])
    # one job dir on its own, into another dir
    job = sweep / "generations=25,k=1,setup=duo"
    main([str(job), "--out", str(tmp_path / "one"), "--format", "pdf"])
    one = json.loads((tmp_path / "one" / "index.json").read_text())
    assert by_name(one)["curves_duo"]["methods"] == ["k=1"] and (tmp_path / "one" / "curves_duo.pdf").exists()
