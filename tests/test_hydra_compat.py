"""Hydra's private API, used in rovermarl/hydra_compat.py only: fails plainly if a Hydra release changes it."""

import inspect

import hydra
from hydra.core.override_parser.overrides_parser import OverridesParser

from rovermarl import hydra_compat


def test_the_private_functions_exist_with_the_signatures_rovermarl_uses():
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra._internal.utils import _run_hydra, get_args_parser

    params = list(inspect.signature(_run_hydra).parameters)
    assert params[:5] == ["args", "args_parser", "task_function", "config_path", "config_name"], (
        f"hydra {hydra.__version__} changed _run_hydra (checked with {hydra_compat.CHECKED_WITH}): {params}")
    assert list(inspect.signature(BasicSweeper.split_arguments).parameters) == ["overrides", "max_batch_size"]
    assert list(inspect.signature(BasicSweeper.validate_batch_is_legal).parameters) == ["self", "batch"]
    assert "self.validate_batch_is_legal(batch)" in inspect.getsource(BasicSweeper.sweep)   # what run() skips
    assert callable(get_args_parser)


def test_parser_and_sweep_expansion_behave_as_rovermarl_expects():
    args = hydra_compat.args_parser().parse_args(["-m", "k=1,2", "setup=solo,duo", "seeds=3"])
    assert args.multirun and args.overrides == ["k=1,2", "setup=solo,duo", "seeds=3"]
    jobs = hydra_compat.split_sweep(OverridesParser.create().parse_overrides(["k=1,2", "setup=solo,duo", "seeds=3"]))
    assert jobs == [["k=1", "setup=solo", "seeds=3"], ["k=1", "setup=duo", "seeds=3"],
                    ["k=2", "setup=solo", "seeds=3"], ["k=2", "setup=duo", "seeds=3"]]


def test_private_api_is_used_in_one_module_only():
    from tests.conftest import ROOT
    users = [p.relative_to(ROOT).as_posix() for p in (ROOT / "rovermarl").rglob("*.py")
             if "hydra._internal" in p.read_text()]
    assert users == ["rovermarl/hydra_compat.py"]
