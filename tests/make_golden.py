"""Regenerate ``tests/data/golden_4c4ae3c.json`` from a checkout of commit 4c4ae3c.

Run this ONLY against commit 4c4ae3c (the reference the reshaped code must match bit for bit), never against
the current code: the golden file would then test nothing. It refuses a checkout whose HEAD is another commit
or whose tracked files are modified::

    git worktree add /work/base 4c4ae3c
    python tests/make_golden.py --base /work/base            # runs the jobs with cwd=/work/base, PYTHONPATH=/work/base

It runs ``tests/golden_jobs.py``'s jobs with the old code, checks that they made exactly the expected job dirs,
and writes the per-array digests (and the command lines, for the record) to the golden file, and the values of the
CPU-dependent arrays (EXP3 probabilities) to ``tests/data/golden_4c4ae3c_probs.npz``. ``--values-only`` keeps the
golden file, checks that every other digest still matches it, and writes only the values.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.golden_jobs import (  # noqa: E402
    COMMIT,
    CPU_DEPENDENT,
    GOLDEN,
    GOLDEN_VALUES,
    GROUPS,
    JOBS,
    command,
    cpu_dependent_values,
    digest_tree,
    job_dirs,
    load_golden,
    run_all,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, required=True, help=f"a clean checkout of {COMMIT}")
    parser.add_argument("--out", type=Path, default=GOLDEN)
    parser.add_argument("--values-only", action="store_true",
                        help="keep the golden file; check its other digests and write only the values file")
    args = parser.parse_args()
    base = args.base.resolve()

    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", str(base), *a], check=True, capture_output=True, text=True).stdout.strip()

    head, full = git("rev-parse", "HEAD"), git("rev-parse", COMMIT)
    if head != full:
        sys.exit(f"make_golden: {base} is at {head[:7]}, not {COMMIT}")
    if git("status", "--porcelain", "--untracked-files=no"):
        sys.exit(f"make_golden: {base} has modified tracked files")
    probe = subprocess.run([sys.executable, "-c", "import rovermarl; print(rovermarl.__file__)"], cwd=base,
                           env={"PYTHONPATH": str(base), "PATH": ""}, capture_output=True, text=True, check=True)
    if not Path(probe.stdout.strip()).resolve().is_relative_to(base):
        sys.exit(f"make_golden: rovermarl imports from {probe.stdout.strip()}, not from {base}")

    with tempfile.TemporaryDirectory(prefix="golden-") as tmp:
        times = run_all(Path(tmp), cwd=base, pythonpath=str(base))
        made = job_dirs(Path(tmp))
        if made != {g: sorted(j) for g, j in JOBS.items()}:
            sys.exit(f"make_golden: unexpected job dirs {made}")
        digests = digest_tree(Path(tmp))
        values = cpu_dependent_values(Path(tmp))
    np.savez_compressed(GOLDEN_VALUES, **values)
    print(f"{len(values)} arrays of {', '.join(CPU_DEPENDENT)} -> {GOLDEN_VALUES}")
    if args.values_only:
        kept = load_golden(args.out)["digests"]
        other = sorted(k for k in kept if k.rsplit("/", 1)[1] not in CPU_DEPENDENT and kept[k] != digests.get(k))
        if other or set(kept) != set(digests):
            sys.exit(f"make_golden: this machine's digests differ from {args.out} beyond {CPU_DEPENDENT}: {other[:3]}")
        return
    golden = {
        "commit": full,
        "commands": {g: " ".join(command(g, Path("<out>"))[1:]) for g in GROUPS},
        "digests": digests,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(golden, indent=1, sort_keys=True) + "\n")
    print(f"{len(digests)} array digests -> {args.out} ({', '.join(f'{g} {t:.1f} s' for g, t in times.items())})")


if __name__ == "__main__":
    main()
