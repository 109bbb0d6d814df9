"""Options classes made from a C++ struct's one description (core/options_description.hpp,
bindings/options_class.hpp): fields, defaults and docs as the struct has them, type and range
errors naming the field's path, nested groups by reference, copies, pickling, the state file's
bytes, and the keyword sugar of the class that takes them (MonteCarloLocalization)."""

import copy
import math
import pickle

import numpy as np
import pytest

import probslam as ps
import walled_room
from probslam import _core

OPTIONS_CLASSES = [ps.OdometryMotionNoise, ps.BeamMixture, ps.MonteCarloLocalizationOptions]


def fields(cls):
    """The field names of an options class, from its docstring's field list."""
    return [line.strip().split(" ")[0].rstrip(":") for line in cls.__doc__.split("Fields:")[1].strip().splitlines()]


def room():
    return walled_room.room(0.1, 40, 30)


@pytest.mark.parametrize("cls", OPTIONS_CLASSES)
def test_every_field_is_a_documented_keyword_with_the_structs_default(cls):
    names = fields(cls)
    assert len(names) == len(set(names)) > 0
    default = cls()
    for name in names:
        assert getattr(type(default), name).__doc__.startswith(name)  # help() shows unit and doc
        value = getattr(default, name)
        assert cls(**{name: value}) == default  # the keyword takes what the property shows
    # The generated signature lists the fields in order, each with the default it shows.
    signature = cls.__init__.__doc__.splitlines()[0]
    assert [p.split(":")[0].strip() for p in signature.split("*, ")[1].split(", ") if ":" in p and "=" in p
            and "(" not in p.split(":")[0]][:2] == names[:2]


def test_the_defaults_are_the_ones_the_filter_uses():
    """A filter built without options runs with MonteCarloLocalizationOptions() (a default written
    twice would drift)."""
    mcl = ps.MonteCarloLocalization(room(), min_particles=20, max_particles=40)
    assert mcl.options == ps.MonteCarloLocalizationOptions(min_particles=20, max_particles=40)
    assert ps.MonteCarloLocalizationOptions().odometry == ps.OdometryMotionNoise(alpha1=0.2, alpha2=0.2,
                                                                                 alpha3=0.2, alpha4=0.2)


def test_errors_name_the_field_path():
    O = ps.MonteCarloLocalizationOptions
    with pytest.raises(TypeError, match="^sigma must be a real number"):
        O(sigma="0.1")
    with pytest.raises(TypeError, match="^max_beams must be an int"):
        O(max_beams=2.5)
    with pytest.raises(TypeError, match="unexpected keyword argument 'sigma_hit'"):  # the beam's name, not the field's
        O(sigma_hit=0.1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'update_min_d'"):  # update.distance now
        O(update_min_d=0.1)
    with pytest.raises(TypeError, match="^odometry: expected an OdometryMotionNoise or a dict"):
        O(odometry=(0.1, 0.1, 0.1, 0.1))
    with pytest.raises(TypeError, match="^odometry got an unexpected keyword argument 'alpha5'"):
        O(odometry={"alpha5": 0.1})
    with pytest.raises(ValueError, match="^odometry.alpha2 must be finite and >= 0"):
        O(odometry={"alpha2": -1.0})
    with pytest.raises(ValueError, match="^beam.sigma_hit must be finite"):
        O(beam={"sigma_hit": math.nan})
    with pytest.raises(ValueError, match='^sensor_model must be one of "likelihood-field", "beam", got "sonar"'):
        O(sensor_model="sonar")
    with pytest.raises(ValueError, match="^min_particles must lie in"):
        O(min_particles=0)
    with pytest.raises(TypeError, match="^seed must be an int"):
        O(seed=True)


def test_a_property_set_through_its_groups_names_the_whole_path():
    """``o.frontend.filter.max_range = "x"`` is refused naming ``frontend.filter.max_range``, as the
    constructor names it; a group standing alone names its own fields."""
    s = ps.SubmapSlamOptions()
    with pytest.raises(TypeError, match="^frontend.filter.max_range must be a real number"):
        s.frontend.filter.max_range = "x"
    with pytest.raises(TypeError, match="^closures.min_match_quality must be a real number"):
        s.closures.min_match_quality = "x"
    frontend = s.frontend
    with pytest.raises(TypeError, match="^frontend.update.distance must be a real number"):
        frontend.update.distance = "x"
    with pytest.raises(TypeError, match="^frontend.filter: expected a ScanFilter or a dict"):
        frontend.filter = 3
    o = ps.MonteCarloLocalizationOptions()
    with pytest.raises(TypeError, match="^odometry.alpha2 must be a real number"):
        o.odometry.alpha2 = "x"
    with pytest.raises(ValueError, match='^sensor_model must be one of'):
        o.sensor_model = "sonar"
    with pytest.raises(TypeError, match="^alpha2 must be a real number"):
        o.odometry.copy().alpha2 = "x"  # a copy stands alone
    with pytest.raises(TypeError, match="^max_range must be a real number"):
        ps.ScanFilter().max_range = "x"
    s.frontend.filter.max_range = 12.0  # and a good value is set through the groups
    assert s.frontend.filter.max_range == 12.0 and s == ps.SubmapSlamOptions(frontend={"filter": {"max_range": 12.0}})


def test_a_failed_set_leaves_the_options_unchanged():
    o = ps.MonteCarloLocalizationOptions(sigma=0.2)
    before = o.copy()
    for field, value in [("sigma", "x"), ("odometry", 3), ("beam", {"z_hit": "x"}), ("sensor_model", "sonar")]:
        with pytest.raises((TypeError, ValueError)):
            setattr(o, field, value)
        assert o == before
    with pytest.raises(ValueError):
        o.replace(min_particles=0)
    assert o == before


def test_groups_are_attributes_by_reference_and_dicts_merge():
    o = ps.MonteCarloLocalizationOptions()
    o.beam.z_hit = 0.8
    o.beam.z_short = 0.1
    assert (o.beam.z_hit, o.beam.z_short) == (0.8, 0.1)
    o.validate()
    o.odometry = {"alpha3": 0.05}  # a dict sets the fields it names
    assert (o.odometry.alpha1, o.odometry.alpha3) == (0.2, 0.05)
    o.odometry = {"alpha1": 0.3}  # ... and keeps the others, as replace and the keywords do
    assert (o.odometry.alpha1, o.odometry.alpha3) == (0.3, 0.05)
    r = o.replace(beam={"sigma_hit": 0.2})
    assert (r.beam.z_hit, r.beam.sigma_hit, o.beam.sigma_hit) == (0.8, 0.2, 0.05)
    with pytest.raises(ValueError, match="^beam.z_hit"):  # the weights no longer sum to 1
        o.replace(beam={"z_hit": 0.9})


@pytest.mark.parametrize("cls", OPTIONS_CLASSES)
def test_copies_pickles_and_repr_are_the_same_options(cls):
    o = cls()
    name = fields(cls)[-1]
    setattr(o, name, getattr(o, name))
    for twin in (o.copy(), copy.copy(o), copy.deepcopy(o), pickle.loads(pickle.dumps(o)),
                 eval(repr(o), {n: getattr(_core, n) for n in dir(_core)})):  # noqa: S307
        assert twin == o and twin is not o
    c = o.copy()
    if isinstance(o, ps.MonteCarloLocalizationOptions):
        c.beam.sigma_hit = 0.3  # a copy's groups are its own
        assert o.beam.sigma_hit == 0.05
    assert (o == 1) is False


def test_keywords_replace_the_given_options_fields():
    base = ps.MonteCarloLocalizationOptions(min_particles=30, max_particles=60, seed=4)
    mcl = ps.MonteCarloLocalization(room(), options=base, seed=9, odometry={"alpha1": 0.01})
    assert mcl.options == base.replace(seed=9, odometry={"alpha1": 0.01})
    assert base.seed == 4  # the caller's options are not touched
    with pytest.raises(TypeError, match="^options: expected a MonteCarloLocalizationOptions, got dict"):
        ps.MonteCarloLocalization(room(), options={"seed": 1})
    with pytest.raises(TypeError, match="unexpected keyword argument 'particles'"):
        ps.MonteCarloLocalization(room(), particles=10)


def test_equal_options_give_equal_filters():
    """Keywords and an options object are one path: the same filter, particle for particle."""
    a = ps.MonteCarloLocalization(room(), initial_pose=[2.0, 1.5, 0.0], min_particles=30, max_particles=60, seed=3,
                                  sigma=0.2)
    b = ps.MonteCarloLocalization(room(), initial_pose=[2.0, 1.5, 0.0],
                                  options=ps.MonteCarloLocalizationOptions(min_particles=30, max_particles=60, seed=3,
                                                                           sigma=0.2))
    assert np.array_equal(a.poses, b.poses)


def test_the_state_file_holds_the_fields_in_describe_order(tmp_path):
    """The options' bytes in a state file are the fields in describe()'s order, groups inline: a
    loaded filter has the same options (each changed from its default, so a field read into
    another's place would show)."""
    o = ps.MonteCarloLocalizationOptions(
        sensor_model="beam", odometry={"alpha1": 0.11, "alpha2": 0.12, "alpha3": 0.13, "alpha4": 0.14},
        occupied_threshold=0.7, free_threshold=0.2, sigma=0.15, p_rand=0.04,
        beam={"z_hit": 0.8, "z_short": 0.1, "z_max": 0.04, "z_rand": 0.06, "sigma_hit": 0.07, "lambda_short": 1.5,
              "max_range": 9.0},
        max_range=12.0, min_range=0.1, max_beams=33, weight_scale=0.2, min_particles=21, max_particles=42,
        kld_epsilon=0.06, kld_z=2.0, bin_xy=0.4, bin_theta=0.2, alpha_slow=0.002, alpha_fast=0.2,
        recovery_ratio=0.6, recovery_updates=2, recovery_candidates=5, resample_threshold=0.4, update={"distance": 0.3,
        "angle": 0.4}, seed=123, threads=2)
    mcl = ps.MonteCarloLocalization(room(), options=o)
    mcl.save(tmp_path / "mcl.psl")
    assert ps.MonteCarloLocalization.load(tmp_path / "mcl.psl").options == o
    assert pickle.loads(pickle.dumps(mcl)).options == o


def test_the_stub_is_what_describe_generates():
    """The stub's options classes and the keyword signatures of the classes that take them are
    scripts/stub_options.py's output for the built module (run it after adding an option)."""
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "stub_options.py"
    spec = importlib.util.spec_from_file_location("stub_options", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    stub = module.STUB.read_text()
    assert module.generated(stub) == stub, "run scripts/stub_options.py"
