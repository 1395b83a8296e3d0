"""World along its seams (issue 42): parameters with one home for their defaults, the policy's config apart, derived
state without hand-set attributes, one place that builds the kernel record."""

from dataclasses import fields
from functools import cached_property

import numpy as np
import pytest
import yaml

from rovermarl import errors
from rovermarl.env import World, make_world, trial
from rovermarl.env.kernel import record
from rovermarl.env.params import Params
from rovermarl.policy import MLP
from rovermarl.resources import CONF_DIR

ENV_YAML = yaml.safe_load((CONF_DIR / "env" / "rovers.yaml").read_text())
NOT_ENV = {"coupling", "value", "policy", "name"}     # the setup's, the policy's and the setup's name


def test_the_env_group_and_the_parameters_are_the_same_keys_with_the_same_defaults():
    params = {f.name: f for f in fields(Params)}
    assert set(params) - NOT_ENV == set(ENV_YAML), "conf/env/rovers.yaml and Params name different keys"
    for key, want in ENV_YAML.items():
        assert params[key].default == want, f"env.{key}: Params' default is not conf/env/rovers.yaml's"


def test_a_default_changed_in_the_yaml_is_the_default_everywhere(tmp_path):
    """The yaml is read, not copied: a copy of the conf with steps=20 gives World(...) 20 steps in a fresh process."""
    import shutil
    import subprocess
    import sys
    conf = tmp_path / "conf"
    shutil.copytree(CONF_DIR, conf)
    text = (conf / "env" / "rovers.yaml").read_text().replace("steps: 15 ", "steps: 20 ")
    (conf / "env" / "rovers.yaml").write_text(text)
    code = (f"import rovermarl.resources as r, pathlib; r.CONF_DIR = pathlib.Path(r'{conf}'); r._load.cache_clear()\n"
            "from rovermarl.env import World, make_world\n"
            "print(World(coupling=(1,), value=(1.0,)).steps, make_world('solo').steps)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["20", "20"]


def test_hidden_is_the_policys_not_a_world_field():
    assert "hidden" not in {f.name for f in fields(World.Params)}
    w = World(coupling=(1, 2), value=(1.0, 2.0), policy=MLP(hidden=4))
    assert w.policy.hidden == w.kernel.hidden == 4 and w.n_params == MLP(4).n_params(w.obs_dim)
    assert make_world("duo", hidden=4).n_params == make_world("duo", policy=MLP(4)).n_params
    assert make_world("duo").policy == MLP() == MLP(hidden=16)
    with pytest.raises(errors.ConfigError, match=r"^policy=8: must be a rovermarl.policy.MLP"):
        World(coupling=(1,), value=(1.0,), policy=8)
    with pytest.raises(errors.ConfigError, match=r"^policy.hidden=0: must be an integer >= 1"):
        make_world("duo", hidden=0)


@pytest.mark.parametrize("setup", ["solo", "duo"])
def test_derived_state_is_cached_properties_only(setup):
    """Every attribute a built world holds is its params or a cached_property of its class: nothing set by hand."""
    w = make_world(setup)
    w.evaluate(np.zeros((w.n_rovers, w.n_params)), w.run_ic(0))
    cached = {name for klass in type(w).__mro__ for name, v in vars(klass).items()
              if isinstance(v, cached_property)}
    held = set(vars(w)) - {"params"}
    assert held and held <= cached, held - cached


def test_the_kernel_record_has_one_builder():
    w = make_world("duo", dtype="float32", reward="any_step")
    again = record.build(w, w.task, w.obs_blocks(), w.layout_dim, w.kernel_extra(), trial.state_dims(w))
    for a, b in zip(w.kernel, again, strict=True):
        if isinstance(a, np.ndarray):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        else:
            assert type(a) is type(b) and a == b
    assert w.kernel.poi_xy.dtype == np.float32 and w.kernel.reward_mode == 1


def test_the_world_holds_its_configuration_as_one_object():
    """Issue 52 item 3: the configuration is an object the World holds (``world.params``), not its base class."""
    w = make_world("duo", steps=12)
    assert not issubclass(World, Params) and type(w.params) is Params and w.steps == w.params.steps == 12
    again = World(w.params)
    assert again.params is w.params and again.kernel.steps == 12
    with pytest.raises(AttributeError, match="immutable"):
        w.steps = 3
    import pickle
    assert repr(pickle.loads(pickle.dumps(w))) == repr(w) and "steps=12" in repr(w)
    with pytest.raises(TypeError, match=r"World\(params\) takes one Params and no keywords"):
        World(w.params, steps=3)


@pytest.mark.parametrize("body, said", [
    ("    radius: float = 1.0\n", r"^Bad declares parameters on the World \(radius\): declare them as fields of "
                                 r"its Params, a @dataclass\(frozen=True\) subclass of World.Params"),
    ("    class Params(World.Params):\n        radius: float = 1.0\n",
     r"^Bad.Params must be a subclass of World.Params decorated with @dataclass\(frozen=True\)"),
])
def test_a_parameter_declared_off_its_params_is_refused_in_one_line(body, said):
    with pytest.raises(TypeError, match=said) as err:
        exec(f"class Bad(World):\n{body}", {"World": World})
    assert "\n" not in str(err.value)


def test_a_world_made_a_dataclass_is_refused_in_one_line():
    from dataclasses import dataclass

    @dataclass(frozen=True, eq=False)
    class Old(World):
        pass

    with pytest.raises(errors.ConfigError, match=r"^Old=@dataclass: a World is no dataclass: declare them as fields"):
        make_world("solo", world=Old)


def test_an_attribute_error_inside_a_world_member_is_its_own():
    """A plug-in member that reads a name it lacks fails with that name, not with the World's property's."""
    class Typo(World):
        def kernel_extra(self):
            return (self.params.wind,)

    with pytest.raises(AttributeError, match="'Params' object has no attribute 'wind'"):
        Typo(coupling=(1,), value=(1.0,))


def test_a_world_module_not_found_says_where_to_run_from_and_its_own_missing_import_does_not(tmp_path, monkeypatch):
    from rovermarl.env.world import world_class
    (tmp_path / "needs_more.py").write_text("import nonexistent_dep_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(errors.ConfigError) as gone:
        world_class("nowhere_mod.W", trust=True)
    assert str(gone.value).endswith("(ModuleNotFoundError: No module named 'nowhere_mod'); run from its module's "
                                    "folder or put that on PYTHONPATH")
    with pytest.raises(errors.ConfigError) as dep:
        world_class("needs_more.W", trust=True)
    assert str(dep.value).endswith("(ModuleNotFoundError: No module named 'nonexistent_dep_xyz')")
