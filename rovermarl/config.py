"""Composition of an invocation's jobs and command-line handling, before any work (and before Ray starts).

``compose_config("k=2", "setup=duo")`` gives the job config the CLI would run; checks of a composed config are in
:mod:`rovermarl.runner.validate`.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import yaml
from omegaconf import DictConfig, OmegaConf

from rovermarl import errors, hydra_compat
from rovermarl.resources import composer, group_names, options
from rovermarl.runner.identity import NOT_IN_DIR_NAMES

_INT = re.compile(r"[+-]?\d+")
_GROUP_OVERRIDE = re.compile(r"^(?P<prefix>[+~]{0,2})(?P<group>[A-Za-z_][\w]*)(?P<at>@[\w.]+)?=(?P<value>.*)$")


def quote_numeric_options(argv: list[str], groups: set[str] | None = None) -> list[str]:
    """Quote integer values of config-group overrides so Hydra reads them as option names (it parses ``k=1`` as the
    int 1 and rejects it as a group override): ``k=1,2,4,adaptive`` -> ``k='1','2','4',adaptive``. Anything else
    (quoted values, ``choice(...)``, non-group keys) is passed through unchanged."""
    groups = group_names() if groups is None else groups
    out = []
    for arg in argv:
        m = _GROUP_OVERRIDE.match(arg)
        if m and m["group"] in groups and not re.search(r"[\"'()\[\]{}]", m["value"]):
            items = [f"'{v.strip()}'" if _INT.fullmatch(v.strip()) else v for v in m["value"].split(",")]
            arg = f"{m['prefix']}{m['group']}{m['at'] or ''}=" + ",".join(items)
        out.append(arg)
    return out


def _readable(text: str) -> str:
    return text.replace("'", "").replace('"', "").replace("/", "_")


def _naming(overrides) -> list[str]:
    """The overrides that name an output dir: those of settings that can change results, sorted."""
    return sorted(str(o) for o in overrides
                  if str(o).lstrip("+~").partition("=")[0].split(".")[0].split("@")[0] not in NOT_IN_DIR_NAMES)


def dirname(task_overrides) -> str:
    """A job's dir name from its overrides (Hydra's ``hydra.overrides.task``):
    ``["setup=solo", "k='1'", "parallel=serial"]`` -> ``k=1,setup=solo``."""
    return _readable(",".join(_naming(task_overrides))) or "default"


def sweepname(task_overrides) -> str:
    """Sweep dir name from the command's overrides, minus settings that do not change results:
    ``["k='1','2',adaptive", "setup=solo,duo", "parallel=serial"]`` -> ``k=1,2,adaptive__setup=solo,duo``."""
    return "__".join(_readable(o) for o in _naming(task_overrides)) or "default"


def job_dirs(argv: list[str], multirun: bool, out: Path) -> list[Path]:
    """The output dir of each job of an invocation into ``out``, as Hydra names them: ``out`` itself, or for a
    multirun ``out/<dirname of the job's overrides>`` (``hydra.sweep.subdir``), in Hydra's order."""
    if not multirun:
        return [Path(out)]
    from hydra.core.override_parser.overrides_parser import OverridesParser
    jobs = hydra_compat.split_sweep(OverridesParser.create().parse_overrides(argv))
    return [Path(out) / dirname(job) for job in jobs]


def compose_jobs(argv: list[str], multirun: bool, config_name: str = "config",
                 config_dir: str | None = None) -> list[DictConfig]:
    """Compose the config of every job an invocation would launch (sweeps expanded as Hydra's basic
    sweeper does). Composition problems raise :class:`~rovermarl.errors.ConfigError`."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        parsed = OverridesParser.create().parse_overrides(argv)
    except HydraException as e:
        raise errors.ConfigError("override", " ".join(argv), _one_line(e)) from None
    sweeps = [o for o in parsed if o.is_sweep_override()]
    if sweeps and not multirun:
        key, _, value = sweeps[0].input_line.partition("=")
        raise errors.ConfigError(key, _readable(value), "is a sweep; add -m (--multirun) to run several jobs")
    jobs = hydra_compat.split_sweep(parsed) if multirun else [list(argv)]
    for job in jobs:
        _check_group_values(job)
    if config_dir:
        if not Path(config_dir).is_dir():
            raise errors.ConfigError("--config-dir", config_dir, "no such directory")
        jobs = [_with_searchpath(job, config_dir) for job in jobs]
    cfgs = []
    with composer() as compose:
        for job in jobs:
            try:
                cfgs.append(compose(config_name, overrides=job))
            except (HydraException, ValueError, TypeError) as e:  # Hydra raises the last two on odd overrides
                raise _composition_error(e, job, config_name, compose) from None
            except yaml.YAMLError as e:   # a config file's YAML: a !!python/... tag (the safe loader refuses it), ...
                where = getattr(e, "problem_mark", None)
                raise errors.ConfigError("config file", str(where.name) if where else "?",
                                         f"unreadable YAML ({type(e).__name__}: {_one_line(e)})") from None
    return cfgs


def _check_group_values(job: list[str]) -> None:
    """Each override has a key, and a config group override names options (Hydra fails obscurely otherwise)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    groups = group_names()
    for o in OverridesParser.create().parse_overrides(job):
        if o.is_delete():
            continue
        if not o.key_or_group:
            raise errors.ConfigError("override", o.input_line, "has no key; expected KEY=VALUE")
        group = o.key_or_group.split("@")[0]
        value = o.value()
        names = value if isinstance(value, list) else [value]
        if group in groups and not all(isinstance(v, str) for v in names):
            hint = f" (quote a number: {group}='{value}')" if isinstance(value, int) else ""
            raise errors.ConfigError(group, value, f"must name an option of the group: {', '.join(options(group))}"
                                     f"{hint}")


def _with_searchpath(job: list[str], config_dir: str) -> list[str]:
    path = f"file://{Path(config_dir).resolve()}"
    for i, arg in enumerate(job):
        if arg.startswith("hydra.searchpath="):
            return job[:i] + [arg.rstrip("]") + f",{path}]"] + job[i + 1:]
    return [*job, f"hydra.searchpath=[{path}]"]


def _composition_error(e: Exception, job: list[str], config_name: str = "config", compose=None) -> errors.ConfigError:
    from hydra.errors import MissingConfigException
    if isinstance(e, MissingConfigException) and e.missing_cfg_file and e.options is not None:
        group, _, option = str(e.missing_cfg_file).rpartition("/")
        note = ""
        if group == "k" and _INT.fullmatch(option):
            note = " (a fixed k must be at most env.n_rovers; k.value=K sets any k on a fixed option)"
        return errors.ConfigError(group, option, "no such option; allowed: " + ", ".join(e.options) + note)
    msg = _one_line(e)
    if isinstance(e, MissingConfigException) and "primary config" in msg:
        return errors.ConfigError("--config-name", config_name, "no such config in conf/ (or --config-dir)")
    m = re.search(r"Could not override '([^']+)'|Error merging override ([^=\s]+)|Multiple values for ([^\s.]+)", msg)
    key = next((g for g in m.groups() if g), "override") if m else "override"
    if re.search(r"Key '([^']+)' is not in struct|To append to your config use", msg):
        allowed = _keys_beside(key, job, config_name, compose)
        return errors.ConfigError(key, _value_of(key, job), f"unknown key{allowed}")
    return errors.ConfigError(key, _value_of(key, job), msg)


def _keys_beside(key: str, job: list[str], config_name: str, compose) -> str:
    """``; allowed: a, b`` and, in a section, how a plug-in's own key is added: the keys of ``key``'s section as its
    options' yaml declares them (the job composed with its group choices and ``hydra.*`` only); empty if that fails."""
    if compose is None:
        return ""
    section = key.rpartition(".")[0]
    name = [a.partition("=")[0].lstrip("+~") for a in job]
    choices = [a for a, k in zip(job, name, strict=True) if k != key and ("." not in k or k.startswith("hydra."))]
    try:
        node = compose(config_name, overrides=choices)
    except Exception:                                   # another problem of the job's choices: no list
        return ""
    node = OmegaConf.select(node, section) if section else node
    if not isinstance(node, DictConfig):
        return ""
    keys = ", ".join(sorted(k for k in node if not k.startswith("_")))
    return f"; allowed: {keys}" + (f" (+{key}=... adds a key a plug-in's yaml lacks)" if section else "")


def _value_of(key: str, job: list[str]):
    for arg in job:
        k, _, v = arg.partition("=")
        if k.lstrip("+~") == key:
            return v
    return None


def _one_line(e: Exception) -> str:
    text = " ".join(str(e).split())
    return text.replace(" Set the environment variable HYDRA_FULL_ERROR=1 for a complete stack trace.", "")


def compose_config(*overrides: str) -> DictConfig:
    """The job config the CLI would compose for ``overrides`` (e.g. ``compose_config("k=2", "setup=duo")``)."""
    with composer() as compose:
        return compose("config", overrides=quote_numeric_options(list(overrides)))


if __name__ == "__main__":      # its one command left with the held-out migration, its one user
    print("rovermarl.config: error: a job's overrides are read back by `python studies/heldout/report.py overrides "
          "JOB_DIR` now", file=sys.stderr)
    raise SystemExit(2)
