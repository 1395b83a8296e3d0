"""A doc's generated section: the text between two marker lines (``<!-- name:begin -->`` and ``<!-- name:end -->``),
read and replaced by the report generators (``studies/<name>/report.py``), written atomically."""

from __future__ import annotations

import re
from pathlib import Path

from rovermarl.analysis.results import ResultsError
from rovermarl.record.atomic import atomic_open


def block(doc: str, begin: str, end: str) -> str | None:
    """The text of ``doc`` between the lines ``begin`` and ``end``, or None when the markers are missing."""
    m = re.search(re.escape(begin) + r"\n(.*?)" + re.escape(end), doc, re.S)
    return m[1] if m else None


def replace(path: Path, begin: str, end: str, section: str) -> None:
    """Replace the section of the doc ``path`` between its markers by ``section`` (one line if they are missing)."""
    text = Path(path).read_text()
    if block(text, begin, end) is None:
        raise ResultsError(f"{path}: no {begin} ... {end} markers")
    new = re.sub(re.escape(begin) + r"\n.*?" + re.escape(end), lambda _: f"{begin}\n{section}{end}", text, flags=re.S)
    with atomic_open(Path(path), "w") as f:
        f.write(new)
