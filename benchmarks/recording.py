"""Recording overhead: a whole job (serial, one core) with ``record=default`` vs ``record=off``.

Prints one JSON line: wall times measured alternately, their medians and ``overhead`` = default / off - 1
(the target is <= 0.10), plus the size of the files written per run.

    python benchmarks/recording.py [--setup duo] [--k 1] [--generations 20000] [--seeds 2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from rovermarl.config import compose_config
from rovermarl.runner.job import run_job


def job_seconds(overrides: list[str], out: Path) -> float:
    t = time.perf_counter()
    run_job(compose_config(*overrides, "parallel=serial", "resume=false"), out)
    return time.perf_counter() - t


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="duo")
    p.add_argument("--k", default="1")
    p.add_argument("--generations", type=int, default=20000, help="the config default")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()
    base = [f"setup={a.setup}", f"k={a.k}", f"generations={a.generations}", f"seeds={a.seeds}"]
    load0 = os.getloadavg()[0]
    times = {"default": [], "off": []}
    with tempfile.TemporaryDirectory() as tmp:
        job_seconds([*base[:2], "generations=50", "seeds=1"], Path(tmp) / "warm")   # numba cache, imports
        for i in range(a.repeats):                                                  # alternate
            for mode in times:
                times[mode].append(job_seconds([*base, f"record={mode}"], Path(tmp) / f"{mode}{i}"))
        run = Path(tmp) / "default0" / "runs" / "seed_000"
        sizes = {f.name: f.stat().st_size for f in sorted(run.iterdir())}
    med = {m: statistics.median(t) for m, t in times.items()}
    print(json.dumps({
        "benchmark": "recording", "config": base, "repeats": a.repeats,
        "seconds_default": round(med["default"], 3), "seconds_off": round(med["off"], 3),
        "overhead": round(med["default"] / med["off"] - 1, 4),
        "runs": {m: [round(x, 3) for x in t] for m, t in times.items()},
        "bytes_per_run": sizes,
        "loadavg_1m_start": round(load0, 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
    }))


if __name__ == "__main__":
    main()
