"""What a JSON or YAML file of a results dir may hold, checked before any of it is used (read through
:mod:`rovermarl.record.safe_read`, the one reader; docs/FAULTS.md lists what is refused):

- the parse (:func:`parse_json`, :func:`parse_yaml`, :func:`checked`): at most :data:`DEPTH` levels of nesting, no
  YAML alias, anchor or tag (refused from the event stream, before anything is built: an alias bomb never expands),
  only finite numbers and integers within 64 bits;
- a schema per file kind (:data:`KINDS`): the types and ranges of the fields a reader uses; other fields pass with
  the parse's checks only;
- a config's interpolations (:func:`resolved`): only plain references (``${policy.init_low}``, or a chain of them)
  to a value or a node free of them, at most :data:`REFERENCES`, so resolving cannot run a resolver or multiply a
  node; the schema checks the config as resolved.

Each failure is :class:`Invalid`, one line naming the file and the field.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field

from rovermarl.errors import printable

DEPTH = 64                    # nesting levels (a summary has 4)
BIG = 1 << 63                 # integers: within 64 bits
REFERENCES = 64               # interpolations in one config (the packaged ones make 10)
RUNS = 100_000                # runs of a job, seeds of a summary
_LONG = re.compile(r"[-+]?[\d_]{20,}")                     # a plain YAML integer past 64 bits
_REFERENCE = re.compile(r"\$\{([A-Za-z_][\w]*(?:\.[A-Za-z_][\w]*)*)\}")


class Invalid(ValueError):
    """A file that breaks its parse rules or its schema: one line naming the file and the field."""


# ---- the parse ---------------------------------------------------------------------------------------------------
def parse_json(data: bytes | str, where, kind: str | None = None):
    """The JSON ``data`` read from ``where``, checked (:func:`checked`)."""
    try:
        value = json.loads(data, parse_constant=_no_constant, parse_float=_finite, parse_int=_integer)
    except RecursionError:
        raise Invalid(f"{where} is nested deeper than {DEPTH} levels") from None
    except ValueError as e:
        raise Invalid(f"{where} is not JSON of finite numbers ({_first(e)})") from None
    return checked(value, where, kind)


def parse_yaml(text: str, where, kind: str | None = None):
    """The plain containers of the YAML ``text`` read from ``where`` (interpolations unresolved), checked."""
    import yaml
    from omegaconf import OmegaConf
    depth = 0
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise Invalid(f"{where} holds a YAML alias or anchor: refused (a results dir's YAML has none)")
            if isinstance(event, yaml.NodeEvent) and event.tag:
                raise Invalid(f"{where} holds a YAML tag {printable(event.tag, 60)}: refused")
            if isinstance(event, yaml.ScalarEvent) and event.style is None and _LONG.fullmatch(event.value):
                line = event.start_mark.line + 1
                raise Invalid(f"{where} holds an integer of {len(event.value)} digits (line {line}): past 64 bits")
            depth += isinstance(event, yaml.CollectionStartEvent) - isinstance(event, yaml.CollectionEndEvent)
            if depth > DEPTH:
                raise Invalid(f"{where} is nested deeper than {DEPTH} levels")
        value = OmegaConf.to_container(OmegaConf.create(text) if text.strip() else OmegaConf.create(), resolve=False)
    except Invalid:
        raise
    except Exception as e:  # noqa: BLE001 - yaml errors, constructor errors, odd nodes: one line
        raise Invalid(f"{where} is not a readable config ({type(e).__name__}: {_first(e)})") from None
    return checked(value, where, kind)


def checked(value, where, kind: str | None = None):
    """``value`` (parsed from ``where``) if it is at most :data:`DEPTH` deep, its numbers finite and its integers
    within 64 bits, and it fits the schema of ``kind`` (its interpolations resolved first); else :class:`Invalid`."""
    stack = [(value, "", 0)]
    while stack:
        node, path, depth = stack.pop()
        if depth > DEPTH:
            raise Invalid(f"{where} is nested deeper than {DEPTH} levels")
        if isinstance(node, dict):
            stack.extend((v, _join(path, k), depth + 1) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, f"{path}[{i}]", depth + 1) for i, v in enumerate(node))
        elif isinstance(node, float) and not math.isfinite(node):
            raise Invalid(f"{where}: {path or 'value'} is {node}, not a finite number")
        elif isinstance(node, int) and not isinstance(node, bool) and not -BIG < node < BIG:
            raise Invalid(f"{where}: {path or 'value'} is an integer past 64 bits")
    if kind is not None:
        try:
            KINDS[kind].check(resolved(value) if kind == "config" else value, "")
        except Invalid as e:
            raise Invalid(f"{where}: {e}") from None
    return value


def resolved(config):
    """``config`` with each plain reference replaced by what it names (through a chain of references); :class:`Invalid`
    for any other interpolation, a reference to nothing or to a node holding one, or too many."""
    refs = [(p, s) for p, s in _strings(config, "") if "${" in s]
    if len(refs) > REFERENCES:
        raise Invalid(f"{refs[0][0]}: {len(refs)} interpolations, more than the {REFERENCES} a config may have")

    def look(path: str, text: str, hops: int = 0):
        m = _REFERENCE.fullmatch(text)
        if m is None:
            raise Invalid(f"{path}: {printable(text, 60)!r} is not a plain reference like ${{policy.init_low}}")
        node = config
        for part in m[1].split("."):
            if not isinstance(node, dict) or part not in node:
                raise Invalid(f"{path}: {text} names nothing in the config")
            node = node[part]
        if isinstance(node, str) and "${" in node and hops < REFERENCES:         # a chain: ${mutation} -> ${payload}
            return look(path, node, hops + 1)
        if any("${" in s for _, s in _strings(node, "")):
            raise Invalid(f"{path}: {text} names a node that holds an interpolation, or a chain of them")
        return node

    def walk(node, path):
        if isinstance(node, dict):
            return {k: walk(v, _join(path, k)) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v, f"{path}[{i}]") for i, v in enumerate(node)]
        return look(path, node) if isinstance(node, str) and "${" in node else node

    return walk(config, "") if refs else config


def _strings(node, path: str):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _strings(v, _join(path, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _strings(v, f"{path}[{i}]")
    elif isinstance(node, str):
        yield path or "value", node


def _join(path: str, key) -> str:
    key = printable(key, 60)
    return f"{path}.{key}" if path else key


def _no_constant(name: str):
    raise ValueError(f"{name} is not a finite number")


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text[:20]} is not a finite number")
    return value


def _integer(text: str) -> int:
    if len(text.lstrip("-")) > 19:
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def _first(e: BaseException) -> str:
    return printable((str(e).strip().splitlines() or [""])[0], 100)


# ---- schemas -----------------------------------------------------------------------------------------------------
def _fail(path: str, problem: str):
    raise Invalid(f"{path or 'value'} {problem}")


@dataclass(frozen=True)
class Number:
    """A finite number in [lo, hi]; ``integer``: an int (never a bool, a string or a list); ``none``: or null."""

    lo: float
    hi: float
    integer: bool = False
    none: bool = False

    def check(self, value, path: str) -> None:
        if value is None and self.none:
            return
        kinds = (int,) if self.integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kinds):
            _fail(path, f"is {_shown(value)}, not {'an integer' if self.integer else 'a number'}")
        if not self.lo <= value <= self.hi:
            _fail(path, f"is {_shown(value)}, outside [{self.lo:g}, {self.hi:g}]")


@dataclass(frozen=True)
class Text:
    """A string of at most ``most`` characters (``none``: or null)."""

    most: int = 1000
    none: bool = False

    def check(self, value, path: str) -> None:
        if value is None and self.none:
            return
        if not isinstance(value, str) or len(value) > self.most:
            _fail(path, f"is {_shown(value)}, not a string of at most {self.most} characters")


@dataclass(frozen=True)
class Flag:
    """true or false."""

    def check(self, value, path: str) -> None:
        if not isinstance(value, bool):
            _fail(path, f"is {_shown(value)}, not true or false")


@dataclass(frozen=True)
class Seq:
    """A list of at most ``most`` items, each ``item`` (``none``: or null)."""

    item: object
    most: int
    none: bool = False

    def check(self, value, path: str) -> None:
        if value is None and self.none:
            return
        if not isinstance(value, list) or len(value) > self.most:
            _fail(path, f"is {_shown(value)}, not a list of at most {self.most} items")
        for i, v in enumerate(value):
            self.item.check(v, f"{path}[{i}]")


@dataclass(frozen=True)
class Table:
    """A mapping of at most ``most`` string keys (matching ``keys``) to ``value``s."""

    value: object
    most: int
    keys: str = r".{1,200}"

    def check(self, value, path: str) -> None:
        if not isinstance(value, dict) or len(value) > self.most:
            _fail(path, f"is {_shown(value)}, not a mapping of at most {self.most} entries")
        for k, v in value.items():
            if not isinstance(k, str) or not re.fullmatch(self.keys, k, re.S):
                _fail(_join(path, k), f"is not a key of the form {self.keys}")
            self.value.check(v, _join(path, k))


@dataclass(frozen=True)
class Record:
    """A mapping whose ``fields`` (those present) are checked; others pass with the parse's checks only."""

    fields: dict = field(default_factory=dict)
    none: bool = False

    def check(self, value, path: str) -> None:
        if value is None and self.none:
            return
        if not isinstance(value, dict):
            _fail(path, f"is {_shown(value)}, not a mapping")
        for k, schema in self.fields.items():
            if k in value:
                schema.check(value[k], _join(path, k))


def _shown(value) -> str:
    if isinstance(value, (dict, list)):
        return f"a {type(value).__name__} of {len(value)}"
    text = printable(repr(value), 40)
    return text if len(text) < 40 else f"a {type(value).__name__} of {len(str(value))} characters"


# The ranges of what a run may be when read back: far beyond every committed run, small enough that re-scoring a
# team (verify: 256 held-out episodes) or sizing its files stays within seconds and memory.
SEED = Number(0, 2**32 - 1, integer=True)
GENERATIONS = Number(0, 10**9, integer=True)
SCORE = Number(-1e12, 1e12)
COUNT = Number(0, 10**18, integer=True)
SECONDS = Number(0, 1e12)
ROVERS = Number(1, 64, integer=True)
K = Record({"value": ROVERS, "arms": Seq(ROVERS, 64, none=True)}, none=True)
SEED_KEYS = r"\d{1,10}"
COMPUTE_JOB = Record({"launches": COUNT, "wall_time_s": SECONDS, "team_evals": COUNT, "agent_steps": COUNT,
                      "own_agent_steps": COUNT})
CONFIG = Record({
    "generations": GENERATIONS, "seeds": Number(1, RUNS, integer=True), "seed": SEED,
    "levels": Seq(SCORE, 64, none=True),
    "env": Record({"n_rovers": ROVERS, "steps": Number(1, 1000, integer=True),
                   "episodes": Number(1, 1024, integer=True)}),
    "policy": Record({"hidden": Number(1, 256, integer=True)}),
    "k": K,
    "setup": Record({"name": Text(200), "coupling": Seq(ROVERS, 1024), "value": Seq(SCORE, 1024)}),
    "algorithm": Record({"k": K, "pop_size": Number(1, 10**5, integer=True)}, none=True),
    "evaluation": Record({"heldout": Number(0, 4096, integer=True), "fresh_ic": Flag()}, none=True),
})
KINDS = {
    "summary": Record({
        "choices": Table(Text(200, none=True), 64), "seeds": Seq(SEED, RUNS), "label": Text(), "setup": Text(),
        "source": Text(), "final_score": Table(SCORE, RUNS, SEED_KEYS), "heldout_score": Table(SCORE, RUNS, SEED_KEYS),
        "median_final_score": Number(-1e12, 1e12, none=True), "median_heldout_score": Number(-1e12, 1e12, none=True),
        "first_generation_reaching": Table(Table(Number(0, 10**9, integer=True, none=True), RUNS, SEED_KEYS), 64),
        "generations": GENERATIONS, "episodes": Number(1, 1024, integer=True), "wall_time_s": SECONDS,
        "team_evals": COUNT, "team_evals_per_s": Number(0, 1e15, none=True), "evals_per_generation": Number(0, 1e9),
        "agent_steps_per_generation": Number(0, 1e15), "own_agent_steps_per_generation": COUNT,
        "compute": COMPUTE_JOB, "train_ic": Text(16), "final_team": Text(16),
        "cpu_s": Table(Number(0, 1e12, none=True), RUNS, SEED_KEYS), "coupling_level": Number(1, 64, integer=True),
        "compile_s": SECONDS}),
    "run": Record({"seed": SEED, "generations": GENERATIONS, "final_score": SCORE, "heldout_score": SCORE,
                   "config_hash": Text(64), "cpu_s": Number(0, 1e12, none=True)}),
    "launch": Record({"started_at": SECONDS, "finished_at": SECONDS, "wall_time_s": SECONDS, "team_evals": COUNT,
                      "runs_advanced": COUNT, "interrupted": Flag()}),
    "compute": Record({"jobs": Table(COMPUTE_JOB, RUNS), "team_evals": COUNT, "own_agent_steps": COUNT,
                       "agent_steps": COUNT, "wall_time_s": SECONDS}),
    "config": CONFIG,
    "hydra": Record({"hydra": Record({"runtime": Record({"choices": Table(Text(200, none=True), 256)})})}),
    "overrides": Seq(Text(1000), 1000),
}
