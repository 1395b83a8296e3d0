"""The Rerun recording's layout (blueprint), orientation and colours, and ``rovermarl.replay`` without a display."""

import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest
import yaml
from rerun.chunk import RrdReader
from rerun.components import InterpolationMode

from rovermarl import palette, replay
from rovermarl.algorithms.base import Series
from rovermarl.env.world import World
from rovermarl.record.rerun_log import write_rrd
from tests.conftest import ROOT

G, E, T1, N, P = 60, 3, 16, 4, 10
STEP_AFTER = InterpolationMode.StepAfter.value
DUO = {"coupling": (2, 1, 1, 1, 1, 2, 1, 1, 1, 1), "value": (3, 1, 1, 1, 1, 3, 1, 1, 1, 1)}
SERIES = (  # as CC-(1+1)-ES declares them, with a bandit k-selector
    Series("k", "int16", doc="rovers mutated"),
    Series("accepted", "bool", doc="children kept"),
    Series("switched", "int16", fill=-1, doc="episodes in which an unmutated rover ends at another POI (-1: not "
                                             "measured)"),
    Series("child_score", "float64", fill=np.nan, doc="F of the evaluated team"),
    Series("probs", "float64", (4,), np.nan, "the selector's probability of each k", ("k1", "k2", "k3", "k4"),
           "bandit"),
)


def fake_result(world: World, generations: int = G, seed: int = 0) -> dict:
    """A run's arrays of the shapes the runner hands to write_rrd, with random values."""
    rng = np.random.default_rng(seed)
    g = generations
    switched = rng.integers(0, E + 1, g).astype(np.int16)
    switched[::5] = -1                                              # not measured
    child = rng.uniform(0, 6, g)
    child[::7] = np.nan                                             # not computed
    probs = rng.dirichlet(np.ones(4), g)
    probs[0] = np.nan
    occ_gen = np.array([0, 10, 25])
    count = rng.integers(0, 3, (len(occ_gen), E, world.n_pois)).astype(np.int8)
    beh_gen = np.array([0, 25, g])
    return {"seed": seed, "score": np.maximum.accumulate(rng.uniform(0, 6, g + 1)),
            "k": rng.integers(1, N + 1, g).astype(np.int16), "accepted": rng.random(g) < 0.3,
            "switched": switched, "child_score": child, "probs": probs,
            "behaviour_generation": beh_gen, "behaviour_score": np.zeros(len(beh_gen)),
            "behaviour_xy": rng.normal(0, 5, (len(beh_gen), E, T1, N, 2)).astype(np.float32),
            "occupancy_generation": occ_gen, "occupancy_count": count}


@pytest.fixture(scope="module")
def duo():
    return World(**DUO)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, duo):
    """(path, result) of a recording of a fake duo run with a bandit."""
    res = fake_result(duo)
    path = write_rrd(tmp_path_factory.mktemp("rrd") / "run.rrd", res, duo, series=SERIES, recording_id="seed_000")
    return path, res


def chunks(path, store=None):
    """entity path -> list of (static?, record batch) of one store of an .rrd."""
    out = {}
    for chunk in RrdReader(str(path)).stream(store=store):
        out.setdefault(str(chunk.entity_path), []).append((chunk.is_static, chunk.to_record_batch()))
    return out


def column(batches, name, static=None):
    """All values of one column over an entity's batches (static only / temporal only when asked)."""
    return [v for s, b in batches if static is None or s == static for v in b.column(name).to_pylist()]


def views(path) -> dict:
    """display name -> {kind, origin, query, <archetype>: {field: value}} of the blueprint of an .rrd."""
    reader = RrdReader(str(path))
    (store,) = reader.blueprints()
    props: dict = {}
    for entity, batches in chunks(path, store).items():
        m = re.fullmatch(r"/view/([^/]+)(?:/(\w+))?", entity)
        if not m:
            continue
        view = props.setdefault(m.group(1), {})
        for _, b in batches:
            for name in b.schema.names:
                if ":" in name:
                    arch, field = name.split(":", 1)
                    value = b.column(name).to_pylist()[0]                  # one row: a list of one value...
                    single = isinstance(value, list) and len(value) == 1 and field != "query"
                    view.setdefault(arch, {})[field] = value[0] if single else value   # ...but for queries
    out = {}
    for v in props.values():
        bp = v["ViewBlueprint"]
        out[bp["display_name"]] = {"kind": bp["class_identifier"], "origin": bp["space_origin"],
                                      "query": v.get("ViewContents", {}).get("query"), **v}
    return out


def rgba(colour) -> int:
    r, g, b = colour
    return (int(r) << 24) | (int(g) << 16) | (int(b) << 8) | 0xFF


# ---- the recording --------------------------------------------------------------------------------------------

def test_recording_carries_the_layout_as_a_blueprint(recorded):
    path, _ = recorded
    reader = RrdReader(str(path))
    assert [s.recording_id for s in reader.recordings()] == ["seed_000"]
    assert len(reader.blueprints()) == 1 and reader.blueprints()[0].application_id == "rovermarl"
    v = views(path)
    assert v["episode 0"]["kind"] == "2D" and "/world/episodes/0/**" in v["episode 0"]["query"]
    assert not any("/world/episodes/1" in q for q in v["episode 0"]["query"])
    assert v["all episodes"]["kind"] == "2D" and v["all episodes"]["query"] == ["/world/**"]
    bounds = v["episode 0"]["VisualBounds2D"]["range"]
    assert bounds["x_range"] == bounds["y_range"] and bounds["x_range"][1] > 13 + 2   # the POIs and their rings
    score = next(d for name, d in v.items() if name.startswith("score"))
    assert score["kind"] == "TimeSeries" and score["query"] == ["/metrics/score", "/metrics/child_score"]
    assert score["TimeAxis"]["view_range"] == {"start": 0, "end": G}             # the whole run, not the last 1000
    assert v["k: rovers mutated"]["origin"] == "/metrics/k"
    assert v["k: rovers mutated"]["ScalarAxis"]["range"] == [0.5, 4.5]
    assert v["probs (bandit)"]["origin"] == "/bandit" and v["probs (bandit)"]["query"] == ["$origin/**"]
    occupancy = next(d for name, d in v.items() if name.startswith("POI occupancy"))
    assert occupancy["query"] == ["/occupancy/**", "- /occupancy/count"]
    assert occupancy["ScalarAxis"]["range"] == [-0.6, P - 0.4] and occupancy["PlotLegend"]["visible"] is False
    assert v["occupancy per episode"]["kind"] == "Tensor" and v["legend"]["kind"] == "TextDocument"


def test_recording_has_the_expected_entities_and_rows(recorded, duo):
    path, res = recorded
    ent = chunks(path)
    expected = {"/world", "/world/pois", "/world/poi_labels", "/world/poi_radius", "/world/start_boxes", "/legend",
                "/metrics/score", "/metrics/k", "/metrics/accepted", "/metrics/switched", "/metrics/child_score",
                "/occupancy/count", *(f"/bandit/k{a}" for a in range(1, 5)), *(f"/occupancy/poi_{j}" for j in range(P)),
                *(f"/world/episodes/{e}/{what}" for e in range(E) for what in ("trajectories", "ends", "rovers"))}
    assert expected <= set(ent), expected - set(ent)
    assert column(ent["/metrics/score"], "Scalars:scalars", static=False) == [[s] for s in res["score"]]
    assert len(column(ent["/metrics/k"], "Scalars:scalars", static=False)) == G
    switched = column(ent["/metrics/switched"], "Scalars:scalars", static=False)      # -1: not measured, left out
    assert len(switched) == np.count_nonzero(res["switched"] != -1) and [-1.0] not in switched
    child = column(ent["/metrics/child_score"], "Scalars:scalars", static=False)
    assert len(child) == np.count_nonzero(~np.isnan(res["child_score"]))
    gens = column(ent["/bandit/k2"], "generation", static=False)
    assert gens == list(range(2, G + 1))                                               # generation 1 was nan
    np.testing.assert_allclose(np.ravel(column(ent["/bandit/k2"], "Scalars:scalars", static=False)),
                               res["probs"][1:, 1])
    assert column(ent["/metrics/child_score"], "SeriesPoints:names", static=True) == [["child_score"]]
    assert column(ent["/metrics/k"], "SeriesLines:interpolation_mode", static=True) == [[STEP_AFTER]]
    assert column(ent["/metrics/score"], "SeriesLines:interpolation_mode", static=True) == [[STEP_AFTER]]
    assert len(column(ent["/world/episodes/1/trajectories"], "LineStrips2D:strips")) == 3     # change points
    assert len(column(ent["/world/episodes/1/rovers"], "step")) == T1
    ((text,),) = column(ent["/legend"], "TextDocument:text")
    assert "episode 0" in text and "step" in text and "rovers mutated" in text


def test_positions_are_world_units_and_the_view_has_y_up(recorded, duo):
    path, res = recorded
    ent = chunks(path)
    ((scale,),) = column(ent["/world"], "Transform3D:scale")
    assert scale == [1.0, -1.0, 1.0]                            # the 2-D view's y points down; this flips it
    (positions,) = column(ent["/world/pois"], "Points2D:positions")
    np.testing.assert_allclose(positions, duo.poi_xy, rtol=1e-6)
    strips = column(ent["/world/episodes/2/trajectories"], "LineStrips2D:strips")
    np.testing.assert_allclose(strips[-1][1], res["behaviour_xy"][-1, 2, :, 1], rtol=1e-6)   # rover 1, as logged
    (labels,) = column(ent["/world/poi_labels"], "Points2D:labels")
    assert labels == [f"POI {j} (c={c})" for j, c in enumerate(duo.coupling)]
    assert "Points2D:labels" not in ent["/world/pois"][0][1].schema.names      # labelled once


def test_colours_come_from_the_palette(recorded, duo):
    path, res = recorded
    ent = chunks(path)
    pois = [rgba(c) for c in palette.poi_rgb(duo.coupling)]
    rovers = [rgba(c) for c in palette.rover_rgb(N)]
    assert column(ent["/world/pois"], "Points2D:colors") == [pois]
    assert column(ent["/world/poi_radius"], "LineStrips2D:colors") == [pois]
    assert column(ent["/world/start_boxes"], "LineStrips2D:colors") == [rovers]
    assert column(ent["/world/episodes/0/trajectories"], "LineStrips2D:colors")[-1] == rovers
    assert column(ent["/world/episodes/0/rovers"], "Points2D:colors")[-1] == rovers
    assert not set(pois) & set(rovers)
    # occupancy lane j: one colour per change, the last one held until the last generation
    mean = res["occupancy_count"].mean(axis=1)
    vmax = max(1.0, mean.max())
    lane = ent["/occupancy/poi_5"]
    assert column(lane, "generation", static=False) == [0, 10, 25, G]
    assert column(lane, "Scalars:scalars", static=False) == [[5.0]] * 4
    expected = [rgba(c) for c in palette.occupancy_rgb(np.r_[mean[:, 5], mean[-1, 5]], vmax)]
    assert np.ravel(column(lane, "SeriesLines:colors", static=False)).tolist() == expected


@pytest.mark.parametrize("setup", sorted(p.stem for p in (ROOT / "conf" / "setup").glob("*.yaml")))
def test_no_colour_is_both_a_poi_and_a_rover(setup):
    cfg = yaml.safe_load((ROOT / "conf" / "setup" / f"{setup}.yaml").read_text())
    n = yaml.safe_load((ROOT / "conf" / "env" / "rovers.yaml").read_text())["n_rovers"]
    if "setup" in cfg:                                                  # `# @package _global_`
        n, cfg = cfg.get("env", {}).get("n_rovers", n), cfg["setup"]
    pois = {tuple(c) for c in palette.poi_rgb(cfg["coupling"])}
    assert not pois & {tuple(c) for c in palette.rover_rgb(n)}, setup


def test_a_resimulated_episode_set_without_series_still_has_a_layout(tmp_path, duo):
    full = fake_result(duo)
    res = {"seed": 0, "score": np.array([2.5]), "behaviour_generation": np.zeros(1, dtype=np.int64),   # as --resim
           "behaviour_score": np.array([2.5]), "behaviour_xy": full["behaviour_xy"][-1:],
           "occupancy_generation": np.zeros(1, dtype=np.int64), "occupancy_count": full["occupancy_count"][-1:]}
    path = write_rrd(tmp_path / "resim.rrd", res, duo)
    v = views(path)
    assert {"episode 0", "all episodes", "legend"} <= set(v)
    assert not any(name.startswith("k") for name in v)
    assert column(chunks(path)["/occupancy/poi_0"], "generation", static=False) == [0]


# ---- replay ---------------------------------------------------------------------------------------------------

def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bound(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_no_viewer_prints_the_native_and_the_web_commands(recorded, capsys):
    path, _ = recorded
    replay.main([str(path), "--no-viewer", "--web-port", "9191", "--grpc-port", "9292"])
    out = capsys.readouterr().out
    assert f"rerun {path.resolve()}" in out
    assert f"--web-viewer --bind 127.0.0.1 --web-viewer-port 9191 --port 9292 {path.resolve()}" in out
    assert "ssh -N -L 9191:127.0.0.1:9191 -L 9292:127.0.0.1:9292 " in out
    assert "open http://localhost:9191/?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A9292%2Fproxy" in out


def test_without_a_display_replay_serves_the_web_viewer_and_stops_cleanly(recorded):
    path, _ = recorded
    web, grpc = free_port(), free_port()
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.Popen([sys.executable, "-m", "rovermarl.replay", str(path), "--web-port", str(web),
                             "--grpc-port", str(grpc)], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        lines = []
        deadline = time.monotonic() + 90
        while not any(ln.strip().startswith("2. open ") for ln in lines) and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
        text = "".join(lines)
        assert text.startswith("no display here"), text + proc.stderr.read() if proc.poll() is not None else text
        assert f"ssh -N -L {web}:127.0.0.1:{web} -L {grpc}:127.0.0.1:{grpc} " in text
        url = text.split("2. open ")[1].split()[0]
        assert url.startswith(f"http://localhost:{web}/?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A{grpc}%2Fproxy")
        with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=10) as r:    # the web viewer is up
            assert r.status == 200
        assert bound(grpc)
        proc.send_signal(signal.SIGTERM)                          # as Ctrl-C, or the ssh session closing
        assert proc.wait(30) == 0
        assert "stopped the web viewer" in proc.stdout.read()
        deadline = time.monotonic() + 10
        while (bound(web) or bound(grpc)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not bound(web) and not bound(grpc)                 # no server left behind
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.parametrize("keep", ["empty", "16 bytes", "half", "between two messages", "without its footer"])
def test_a_truncated_rrd_is_a_one_line_error(recorded, tmp_path, capsys, keep):
    path, _ = recorded
    data = path.read_bytes()
    n = {"empty": 0, "16 bytes": 16, "half": len(data) // 2, "without its footer": len(data) - 10}.get(keep)
    cut = tmp_path / "cut.rrd"
    if n is None:                                 # a recording still being written: whole messages, no footer
        import rerun as rr
        rec = rr.RecordingStream("rovermarl", recording_id="cut")
        rec.save(str(tmp_path / "live.rrd"))
        rec.log("metrics/score", rr.Scalars(1.0))
        rec.flush()
        data = (tmp_path / "live.rrd").read_bytes()
        rec.disconnect()
        assert data and RrdReader(str(tmp_path / "live.rrd")).recordings()   # complete once disconnected
        n = len(data)
    cut.write_bytes(data[:n])
    with pytest.raises(SystemExit) as e:
        replay.main([str(cut), "--no-viewer"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and len(err) == 1, err
    assert err[0].startswith(f"rovermarl.replay: error: {cut}: not a readable Rerun recording"), err
