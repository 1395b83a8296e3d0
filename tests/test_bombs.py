"""Small files that would allocate gigabytes, and checkpoints trusted beyond their checksum (issue 39). Each read
checks every member's declared shape and size against what the config implies before it inflates or allocates
anything: peak memory (measured in a subprocess, ``ru_maxrss``) stays within twice the legitimate file's size plus
100 MB; a doctored checkpoint is ignored with one line and the run starts afresh."""

import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from rovermarl.record.checkpoint import MAGIC, RunRecord
from rovermarl.runner.chunk import advance, parts, to_plain
from rovermarl.runner.identity import config_hash
from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli, run_study

ARGS = ("setup=duo", "k=1", "generations=300", "seeds=1", "parallel=serial", "parallel.chunk=100",
        "checkpoint.every=100", "record=off")
ZEROS = 150_000_000                                   # float64: 1.2 GB inflated, about 1.2 MB deflated
MB = 1 << 20


def _npy_header(shape, descr="<f8") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _deflated_zeros(zf: zipfile.ZipFile, name: str, n: int = ZEROS) -> None:
    """A member ``name`` of ``n`` float64 zeros, written deflated in a stream (small on disk)."""
    block = bytes(16 * MB)
    info = zipfile.ZipInfo(name)
    info.compress_type, info._compresslevel = zipfile.ZIP_DEFLATED, 9
    with zf.open(info, "w", force_zip64=True) as m:
        m.write(_npy_header((n,)))
        left = n * 8
        while left:
            m.write(block[:min(left, len(block))])
            left -= min(left, len(block))


def _zip(path_or_buf, members: dict, bomb: str) -> None:
    """An npz of ``members`` (stored, as numpy writes them) plus the deflated ``bomb`` member."""
    with zipfile.ZipFile(path_or_buf, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as zf:
        for key, value in members.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(value))
            zf.writestr(zipfile.ZipInfo(f"{key}.npy"), buf.getvalue(), compress_type=zipfile.ZIP_STORED)
        _deflated_zeros(zf, f"{bomb}.npy")


def _peak_mb(code: str) -> float:
    """Peak resident memory (MB) of a Python process that runs ``code`` (exceptions printed, not raised)."""
    script = ("try:\n" + "".join(f"    {line}\n" for line in code.splitlines()) +
              "except BaseException as e:\n    print(type(e).__name__, e)\n"
              "import resource\nprint('PEAK', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    peak = [line for line in proc.stdout.splitlines() if line.startswith("PEAK")]
    assert peak, proc.stdout + proc.stderr[-2000:]
    return int(peak[-1].split()[1]) / 1024


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    path = tmp_path_factory.mktemp("bombs") / "sweep" / "job"
    run_job(make_cfg("setup=duo", "generations=30", "seeds=1", "parallel=serial"), path)
    return path


@pytest.mark.slow                                       # about a minute: deflating 1.2 GB of zeros, twice
def test_a_curve_bomb_is_read_within_the_memory_target(job, tmp_path):
    legit = job.parent
    bombed = tmp_path / "sweep"
    shutil.copytree(legit, bombed)
    curve = bombed / "job" / "runs" / "seed_000" / "curve.npz"
    size = curve.stat().st_size
    with np.load(curve) as z:
        members = {k: z[k] for k in z.files if k != "score"}
    _zip(curve, members, "score")
    assert curve.stat().st_size < 2 * MB
    read = "from rovermarl.analysis.sweep import find_jobs\nprint(find_jobs({!r})[1])"
    base, peak = _peak_mb(read.format(str(legit))), _peak_mb(read.format(str(bombed)))
    assert peak - base < 2 * size / MB + 100, (base, peak)
    relaunch = ("from rovermarl.record.outputs import load_score\n"
                f"load_score({str(curve.parent)!r}, 30)")
    assert _peak_mb(relaunch) - _peak_mb("import rovermarl.record.outputs") < 2 * size / MB + 100


def _checkpoint(path, cfg_args=ARGS):
    """A real checkpoint of seed 0 at generation 100; returns the config hash."""
    plain = to_plain(make_cfg(*cfg_args))
    rec = RunRecord(0, 300, parts(plain).algorithm.series)
    rec.add(advance(plain, 0, None, 100))
    path.parent.mkdir(parents=True, exist_ok=True)
    rec.save(path, config_hash(plain))
    return config_hash(plain)


def _rewrite(path, edit) -> None:
    """Apply ``edit(arrays, meta)`` to a checkpoint's payload and give it a valid checksum again."""
    payload = path.read_bytes().partition(b"\n")[2]
    with np.load(io.BytesIO(payload)) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("_meta")))
    buf = edit(arrays, meta)
    if buf is None:
        buf = io.BytesIO()
        np.savez(buf, _meta=np.array(json.dumps(meta)), **arrays)
    payload = buf.getvalue()
    path.write_bytes(MAGIC + b" " + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)


@pytest.mark.slow
def test_a_checkpoint_with_an_extra_inflating_member_is_refused_within_the_memory_target(tmp_path):
    path = tmp_path / "checkpoint.bin"
    key = _checkpoint(path)
    size = path.stat().st_size

    def bomb(arrays, meta):
        buf = io.BytesIO()
        _zip(buf, {"_meta": np.array(json.dumps(meta)), **arrays}, "extra")
        return buf
    _rewrite(path, bomb)
    read = ("from rovermarl.record.checkpoint import resume\n"
            f"print('RESUMED', resume({str(path)!r}, {key!r}, print, 300))")
    peak = _peak_mb(read) - _peak_mb("import rovermarl.record.checkpoint")
    assert peak < 2 * size / MB + 100, peak


def test_a_genomes_header_claiming_terabytes_is_one_line(job, tmp_path):
    run = tmp_path / "job" / "runs" / "seed_000"
    shutil.copytree(job, tmp_path / "job")
    (run / "genomes.npy").write_bytes(_npy_header((4, 10**11)) + bytes(64))
    proc = run_cli(str(run), "--resim", "--no-viewer", module="rovermarl.replay")
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and "genomes.npy" in lines[0], proc.stderr[-2000:]


def _parents_of_4_by_3(arrays, meta):
    arrays["state/algorithm/parents"] = np.zeros((4, 3))


def _rng_named_seed(arrays, meta):
    meta["state"]["algorithm"]["rng_mut"]["bit_generator"] = "seed"


@pytest.mark.parametrize("edit", [_parents_of_4_by_3, _rng_named_seed])
def test_a_doctored_checkpoint_is_ignored_in_one_line_and_the_run_starts_afresh(tmp_path, edit):
    want = run_job(make_cfg(*ARGS), tmp_path / "ref")
    job = tmp_path / "job"
    _checkpoint(job / "runs" / "seed_000" / "checkpoint.bin")
    _rewrite(job / "runs" / "seed_000" / "checkpoint.bin", edit)
    code = ("import json, logging, sys\nlogging.basicConfig(level=logging.WARNING, stream=sys.stderr)\n"
            "from tests.conftest import make_cfg\nfrom rovermarl.runner.job import run_job\n"
            f"print(json.dumps(run_job(make_cfg(*{ARGS!r}), {str(job)!r})['final_score']))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=600,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})       # a kernel reading past an array
    assert proc.returncode == 0, proc.stderr[-2000:]
    warned = [x for x in proc.stderr.splitlines() if x.startswith("WARNING")]
    assert len(warned) == 1 and "checkpoint.bin" in warned[0] and "starts from scratch" in warned[0], proc.stderr
    assert json.loads(proc.stdout) == want["final_score"]


# ---- issue 51: bombs and wrong types in the json and yaml a reader parses -------------------------------------------
# Each is planted in the first job of a two-job sweep; plot, export, verify and heldout merge end within 60 s, say
# one line naming the file (and the field), and go on with the other job; replay --resim refuses in one line.
SWEEP2 = ("-m", "k=1,2", "setup=duo", "generations=30", "seeds=1", "parallel=serial")
BOMBED, OTHER = "generations=30,k=1,setup=duo", "generations=30,k=2,setup=duo"
ALIAS_BOMB = "a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"{n}: &{n} [{','.join([f'*{p}'] * 9)}]\n" for p, n in zip("abcdefgh", "bcdefghi", strict=True))   # 9**9 x expanded


def _summary_text(text: str):
    return lambda old: text


def _summary_edit(key, value):
    def edit(old: str) -> str:
        data = json.loads(old)
        data[key] = value
        return json.dumps(data)
    return edit


def _config_line(old_line: str, new_line: str):
    return lambda old: old.replace(old_line, new_line, 1)


BOMBS = {   # name: (file under the job dir, edit of its text, what the one line names)
    "yaml alias bomb": (".hydra/config.yaml", lambda old: ALIAS_BOMB, "alias"),
    "json nested 200,000 deep": ("summary.json", _summary_text("[" * 200_000 + "]" * 200_000), "nested deeper"),
    "seeds as strings": ("summary.json", _summary_edit("seeds", ["0"]), "seeds[0]"),
    "a list for a score": ("summary.json", _summary_edit("median_final_score", [1, 2]), "median_final_score"),
    "k of 5,000 digits": (".hydra/config.yaml", _config_line("  value: 1\n", "  value: " + "7" * 5000 + "\n"),
                          "5000 digits (line"),
    "env.steps=1e8": (".hydra/config.yaml", _config_line("  steps: 15\n", "  steps: 100000000\n"), "env.steps"),
    "n_rovers=1e6": (".hydra/config.yaml", _config_line("  n_rovers: 4\n", "  n_rovers: 1000000\n"), "env.n_rovers"),
    "NaN score": ("summary.json", lambda old: old.replace('"median_final_score": ', '"median_final_score": NaN, '
                                                          '"x": ', 1), "NaN"),
    "10**400 score": ("summary.json", lambda old: old.replace('"median_final_score": ', '"median_final_score": '
                                                              + "1" + "0" * 400 + ', "x": ', 1), "401 digits"),
    "inf score": ("summary.json", lambda old: old.replace('"median_final_score": ', '"median_final_score": 1e400, '
                                                          '"x": ', 1), "1e400"),
}


@pytest.fixture(scope="module")
def sweep2(tmp_path_factory):
    path = tmp_path_factory.mktemp("bombs") / "sweep"
    proc = run_cli(*SWEEP2, f"hydra.sweep.dir={path}", timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return path


def _named_once(proc, where: str, what: str) -> str:
    """The one line of ``proc``'s output that names ``where``; no traceback."""
    out = proc.stdout + proc.stderr
    assert "Traceback" not in out and "RecursionError" not in out, out[-3000:]
    lines = [x for x in out.splitlines() if where in x]
    assert len(lines) == 1 and what in lines[0], out[-3000:]
    return lines[0]


@pytest.mark.parametrize("bomb", sorted(BOMBS))
def test_a_bomb_or_wrong_type_in_a_results_file_is_one_line_and_the_other_jobs_go_on(sweep2, tmp_path, bomb):
    name, edit, what = BOMBS[bomb]
    sw = tmp_path / "sweep"
    shutil.copytree(sweep2, sw)
    shutil.rmtree(sw / "figures", ignore_errors=True)
    path = sw / BOMBED / name
    path.write_text(edit(path.read_text()))
    where = f"{BOMBED}/{name}"
    plot = run_cli(str(sw), "--format", "png", module="rovermarl.plot", timeout=60)
    assert plot.returncode == 0 and _named_once(plot, where, what).endswith("job skipped")
    export = run_cli("export", str(sw), str(tmp_path / "out"), "--no-fig6", module="rovermarl.analysis", timeout=60)
    assert export.returncode == 0 and _named_once(export, where, what)
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if p.is_dir()) == [OTHER]    # nothing copied
    verify = run_cli("verify", str(sw), module="rovermarl.analysis", timeout=60)
    assert verify.returncode == 2 and _named_once(verify, where, what).startswith("rovermarl.analysis: error: ")
    assert f"ok  {OTHER}: 1 teams re-score" in verify.stdout
    if name == "summary.json":
        merge = run_study("heldout", "merge", str(sw), str(sweep2), timeout=60)
        assert merge.returncode == 0 and _named_once(merge, where, what).endswith("skipped")
    else:
        resim = run_cli(str(sw / BOMBED / "runs" / "seed_000"), "--resim", "--no-viewer", module="rovermarl.replay",
                        timeout=60)
        assert resim.returncode == 2 and _named_once(resim, where, what).startswith("rovermarl.replay: error: ")


def test_a_relaunch_rebuilds_a_summary_nested_200000_deep_in_one_warning(sweep2, tmp_path):
    sw = tmp_path / "sweep"
    shutil.copytree(sweep2, sw)
    (sw / BOMBED / "summary.json").write_text("[" * 200_000 + "]" * 200_000)
    proc = run_cli(*SWEEP2, f"hydra.sweep.dir={sw}", timeout=120)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert json.loads((sw / BOMBED / "summary.json").read_text())["seeds"] == [0]


def test_an_invocations_log_over_64_mb_is_read_in_chunks(sweep2, tmp_path):
    sw = tmp_path / "sweep"
    shutil.copytree(sweep2, sw)
    line = json.dumps({"wall_time_s": 1.0, "team_evals": 2, "pad": "x" * 4000}) + "\n"
    n = (65 << 20) // len(line) + 1
    with open(sw / BOMBED / "invocations.jsonl", "w") as f:
        f.writelines([line] * n)
    proc = run_cli("export", str(sw), str(tmp_path / "out"), "--no-fig6", module="rovermarl.analysis", timeout=60)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert json.loads((tmp_path / "out" / BOMBED / "summary.json").read_text())["compute"]["launches"] == n
    with open(sw / BOMBED / "invocations.jsonl", "a") as f:
        f.write('{"wall_time_s": NaN, "team_evals": 2}\n')
    proc = run_cli("export", str(sw), str(tmp_path / "out2"), "--no-fig6", module="rovermarl.analysis", timeout=60)
    assert proc.returncode == 2 and _named_once(proc, f"invocations.jsonl: line {n + 1}", "NaN")


def test_a_relaunch_appends_to_an_invocations_log_over_64_mb(sweep2, tmp_path):
    """The relaunch copies the log in chunks into a new file, its own line last: no traceback, nothing lost."""
    sw = tmp_path / "sweep"
    shutil.copytree(sweep2, sw)
    line = json.dumps({"wall_time_s": 1.0, "team_evals": 2, "pad": "x" * 4000}) + "\n"
    n = (65 << 20) // len(line) + 1
    with open(sw / BOMBED / "invocations.jsonl", "w") as f:
        f.writelines([line] * n)
    for run in (sw / BOMBED / "runs").iterdir():
        (run / "run.json").unlink()                                      # the relaunch has work to do
    proc = run_cli(*SWEEP2, f"hydra.sweep.dir={sw}", timeout=120)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    with open(sw / BOMBED / "invocations.jsonl") as f:
        lines = f.readlines()
    assert len(lines) == n + 1 and lines[0] == line and json.loads(lines[-1])["team_evals"] > 2


@pytest.mark.parametrize("command", [("selectors",), ("claims",), ("plot",)])
def test_a_bomb_in_committed_results_is_one_line(tmp_path, command):
    results = tmp_path / "paper"
    shutil.copytree(ROOT / "results" / "paper", results, ignore=shutil.ignore_patterns("figures"))
    (results / BOMBED.replace("30", "200000") / "config.yaml").write_text(ALIAS_BOMB)
    if command == ("plot",):
        proc = run_cli(str(results), "--out", str(tmp_path / "figures"), "--format", "png", module="rovermarl.plot",
                       timeout=60)
    elif command == ("claims",):                                        # the paper study's report
        proc = run_study("paper", str(results), timeout=60)
    else:
        proc = run_cli(*command, str(results), module="rovermarl.analysis", timeout=60)
    line = _named_once(proc, "config.yaml", "holds a YAML alias or anchor: refused")
    assert proc.returncode == 2 and line.endswith(": refused (a results dir's YAML has none)"), line
