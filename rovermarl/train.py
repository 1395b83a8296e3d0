"""Train: ``python -m rovermarl.train [-m] [group=option ...] [key=value ...]``.

Every job of an invocation is composed and validated before anything runs (and before Ray starts);
a bad config exits with status 2 and one line on stderr.
"""

from __future__ import annotations

import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from rovermarl.config import compose_jobs, dirname, quote_numeric_options, validate
from rovermarl.env.world import CONF_DIR
from rovermarl.errors import ConfigError
from rovermarl.job import GROUPS, run_job

OmegaConf.register_new_resolver("rovermarl_dirname", dirname, replace=True)


@hydra.main(config_path=str(CONF_DIR), config_name="config", version_base="1.3")
def hydra_main(cfg: DictConfig) -> float:
    hc = HydraConfig.get()
    choices = {g: hc.runtime.choices[g] for g in GROUPS if g in hc.runtime.choices}
    name = dirname(hc.job.override_dirname) if hc.job.override_dirname else "run"
    return run_job(cfg, Path(hc.runtime.output_dir), name=name, choices=choices)["median_final_score"]


def check(argv: list[str]) -> None:
    """Compose and validate every job of ``argv`` (already quoted); raises ConfigError."""
    from hydra._internal.utils import get_args_parser
    args = get_args_parser().parse_args(argv)
    if args.help or args.hydra_help or args.cfg or args.info or args.shell_completion:
        return  # Hydra's own informational modes
    for cfg in compose_jobs(args.overrides, args.multirun, args.config_name or "config", args.config_dir):
        validate(cfg)


def main(argv: list[str] | None = None) -> None:
    argv = quote_numeric_options(list(sys.argv[1:] if argv is None else argv))
    try:
        check(argv)
    except ConfigError as e:
        print(f"rovermarl.train: error: {e}", file=sys.stderr)
        sys.exit(2)
    sys.argv = [sys.argv[0], *argv]
    hydra_main()


if __name__ == "__main__":
    main()
