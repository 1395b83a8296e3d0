"""The current code gives bit-identical arrays to commit 4c4ae3c on a fixed set of CLI jobs.

The jobs and the digest are in ``tests/golden_jobs.py``; the reference digests in
``tests/data/golden_4c4ae3c.json`` were made from 4c4ae3c by ``tests/make_golden.py``. The EXP3 probabilities
are compared within a few ulp (numpy's ``exp`` depends on the CPU; see ``tests/golden_jobs.py``).
"""

from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROOT
from tests.golden_jobs import (
    GROUPS,
    JOBS,
    command,
    compare,
    cpu_dependent_values,
    digest_tree,
    job_dirs,
    load_golden,
    load_golden_values,
    run_all,
)


@pytest.mark.slow
def test_cli_jobs_bit_identical_to_4c4ae3c(tmp_path):
    golden = load_golden()
    now = {g: " ".join(command(g, Path("<out>"))[1:]) for g in GROUPS}
    assert golden["commands"] == now, "the golden jobs changed: regenerate the golden file from 4c4ae3c"
    run_all(tmp_path, cwd=ROOT, pythonpath=str(ROOT))
    assert job_dirs(tmp_path) == {g: sorted(j) for g, j in JOBS.items()}, "job dir names changed"
    problem = compare(golden["digests"], digest_tree(tmp_path), load_golden_values(), cpu_dependent_values(tmp_path))
    assert problem is None, problem


def test_probabilities_pass_only_within_a_few_ulp():
    a = np.array([0.25, 0.5, 0.125, 0.125])
    digest = {"k": "x"}
    near = a + 2 * np.spacing(a)
    assert compare(digest, {"k": "y"}, {"k": a}, {"k": near}) is None
    assert compare(digest, {"k": "y"}, {"k": a}, {"k": a + 1e-9}) is not None
    assert compare(digest, {"k": "y"}) is not None                      # no values: the digest decides
