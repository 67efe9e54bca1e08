"""sik_node's parameter table (sik_ros.ros.params): NodeParams, descriptors, validate, the YAML."""

import dataclasses
import math
from pathlib import Path
import random

import pytest
from rcl_interfaces.msg import ParameterType
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
import yaml

from sik_ros.ros import params
from sik_ros.ros.params import NodeParams, SPEC, SPECS, validate
from sik_ros.solver.config import PathDefaults, SolverConfig

REPO = Path(__file__).resolve().parents[1]
READ_ONLY = {'robot', 'model_dir', 'base_frame', 'tip_frame', 'solver_processes',
             'goal_solver_process',
             'robot_description', 'lifecycle', 'command_format', 'command_topic', 'learning',
             'learning_time', 'learning_rows', 'cache_dir', 'sweep_time',
             'moveit_services', 'compute_ik_service', 'compute_fk_service'}


def yaml_parameters():
    """The ``ros__parameters`` of ``config/panda.yaml``."""
    doc = yaml.safe_load((REPO / 'config' / 'panda.yaml').read_text())
    return doc['/**']['ros__parameters']


def in_range(spec, value):
    """Whether a number lies within its declared (closed) range."""
    return spec.min <= value <= spec.max


# -- the table and what is derived from it ------------------------------------------------------

def test_node_params_made_from_the_table():
    """The fields of NodeParams are the table's, in order, with its types and defaults; frozen."""
    got = [(f.name, f.type, f.default) for f in dataclasses.fields(NodeParams)]
    assert got == [(s.name, s.type, s.default) for s in SPECS]
    with pytest.raises(dataclasses.FrozenInstanceError):
        NodeParams().timeout = 1.0
    assert dataclasses.replace(NodeParams(), timeout=1.0).timeout == 1.0


def test_read_only_and_descriptions_come_from_the_table():
    """The read-only set and the descriptions are the table's; the read-only ones as documented.

    The read-only parameters identify the loaded bundle, the solver processes, the arm's
    source and the MoveIt services: changed by a restart only.
    """
    assert set(params.READ_ONLY) == {s.name for s in SPECS if s.read_only} == READ_ONLY
    assert params.DESCRIPTIONS == {s.name: s.description for s in SPECS}
    assert len({s.name for s in SPECS}) == len(SPECS)


def test_the_interfaces_table_is_made_from_the_table():
    """docs/interfaces.md's parameter table is what ``scripts/params_table.py`` makes of SPECS."""
    text = (REPO / 'docs' / 'interfaces.md').read_text()
    head, _, rest = text.partition('<!-- begin: parameters -->\n')
    table, _, _ = rest.partition('<!-- end: parameters -->')
    assert head and table == params.markdown_table(), 'run python scripts/params_table.py'
    for s in SPECS:
        assert f'| `{s.name}` | {s.type.__name__} |' in table, s.name


def test_command_output_settings_checked():
    """command_format takes its three values only, and a command needs a topic."""
    for fmt in params.COMMAND_FORMATS:
        assert validate(NodeParams(command_format=fmt)) is None
    reason = validate(NodeParams(command_format='position'))
    assert reason is not None and 'command_format' in reason
    reason = validate(NodeParams(command_format='joint_trajectory', command_topic=''))
    assert reason is not None and 'command_topic' in reason
    assert validate(NodeParams(goal_num_solutions=65)) is not None, 'over max_solutions_cap'


def test_table_is_consistent():
    """Defaults have their type and lie in range; units are in the descriptions; ranges sane."""
    for s in SPECS:
        assert type(s.default) is s.type, s
        assert s.description, s
        assert s.numeric == (s.type in (int, float)), s
        if s.numeric:
            assert s.min is not None and s.max is not None and s.min < s.max, s
            assert in_range(s, s.default) and (not s.min_open or s.default > s.min), s
        else:
            assert s.min is None and s.max is None and not s.min_open, s
        if s.unit:
            assert f'[{s.unit}]' in s.description, s
        if s.max_param:
            assert SPEC[s.max_param].type is s.type, s
            assert s.max >= SPEC[s.max_param].max, s
    assert validate(NodeParams()) is None


def test_numeric_descriptors_carry_a_range():
    """Every int or float descriptor has exactly one range with the table's bounds."""
    descriptors = params.descriptors()
    assert list(descriptors) == [s.name for s in SPECS]
    for s in SPECS:
        d = descriptors[s.name]
        assert d.name == s.name and d.description == s.description
        assert d.read_only == s.read_only
        if s.type is int:
            assert d.type == ParameterType.PARAMETER_INTEGER
            assert len(d.integer_range) == 1 and not d.floating_point_range, s.name
            r = d.integer_range[0]
            assert (r.from_value, r.to_value, r.step) == (s.min, s.max, 1)
        elif s.type is float:
            assert d.type == ParameterType.PARAMETER_DOUBLE
            assert len(d.floating_point_range) == 1 and not d.integer_range, s.name
            r = d.floating_point_range[0]
            assert (r.from_value, r.to_value, r.step) == (s.min, s.max, 0.0)
        else:
            assert not d.integer_range and not d.floating_point_range, s.name
        if s.min_open:
            assert '>' in d.additional_constraints, s.name
        if s.max_param:
            assert s.max_param in d.additional_constraints, s.name


# -- config/panda.yaml --------------------------------------------------------------------------

def test_panda_yaml_names_exactly_the_declared_parameters():
    """config/panda.yaml sets every declared parameter, and nothing else."""
    assert set(yaml_parameters()) == {s.name for s in SPECS}


def test_panda_yaml_solver_values_are_the_library_defaults():
    """The parameters that set solver settings default to SolverConfig's values, as the yaml.

    (Path defaults are no node parameters: a request's 0 means PATH_DEFAULTS'.)
    """
    values, solver = yaml_parameters(), SolverConfig()
    shared = {f.name for f in dataclasses.fields(SolverConfig)} & set(values)
    assert shared >= {'max_solutions_cap', 'position_tolerance', 'orientation_tolerance'}
    for name in shared:
        assert values[name] == SPEC[name].default == getattr(solver, name), name
    assert not {f.name for f in dataclasses.fields(PathDefaults)} & set(values)


def test_panda_yaml_values_are_valid():
    """Its values have the declared types, lie in the declared ranges and pass validate()."""
    values = yaml_parameters()
    for name, value in values.items():
        s = SPEC[name]
        assert type(value) is s.type, (name, value)
        if s.numeric:
            assert in_range(s, value) and (not s.min_open or value > s.min), (name, value)
    assert validate(NodeParams(**values)) is None


# -- validate -----------------------------------------------------------------------------------

@pytest.mark.parametrize('changes, message', [
    ({'robot': '', 'model_dir': '', 'robot_description': '<robot name="a"/>'},
     'an arm from robot_description needs base_frame and tip_frame'),
    ({'learning_time': 10.0}, 'learning_time must be in [30, 86400] s; got 10.0'),
    ({'solver_processes': 17}, 'solver_processes must be in 0..16; got 17'),
    ({'max_solutions_cap': 0}, 'max_solutions_cap must be in 1..1024; got 0'),
    ({'num_solutions': 65}, 'num_solutions must be in 1..max_solutions_cap (64); got 65'),
    ({'num_solutions': 0}, 'num_solutions must be in 1..max_solutions_cap (64); got 0'),
    ({'position_tolerance': 0.0}, 'position_tolerance must be in (0, 0.1] m; got 0.0'),
    ({'orientation_tolerance': math.nan}, 'orientation_tolerance must be in (0, 3.14159] rad'),
    ({'timeout': 0.0}, 'timeout must be in (0, 60] s; got 0.0'),
    ({'timeout': 61.0}, 'timeout must be in (0, 60] s; got 61.0'),
])
def test_validate_rejects_with_a_reason(changes, message):
    """Each rule that a descriptor cannot express (or that it does) is checked by validate()."""
    reason = validate(dataclasses.replace(NodeParams(), **changes))
    assert reason is not None and reason.startswith(message), reason


def test_validate_accepts_edges():
    """Closed upper bounds and a model_dir instead of robot are fine."""
    for changes in ({'robot': '', 'model_dir': '/some/bundle'}, {'timeout': 60.0},
                    {'robot': '', 'model_dir': ''},  # the robot_description topic's arm
                    {'num_solutions': 3, 'max_solutions_cap': 3}, {'solver_processes': 16},
                    {'orientation_tolerance': math.pi}, {'position_tolerance': 0.1}):
        assert validate(dataclasses.replace(NodeParams(), **changes)) is None, changes


# -- rclpy enforces the descriptors -------------------------------------------------------------

@pytest.fixture
def context(monkeypatch):
    """A private rclpy context on a random domain, discovery on localhost."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    ctx = Context()
    rclpy.init(context=ctx, domain_id=random.SystemRandom().randint(1, 100),
               signal_handler_options=SignalHandlerOptions.NO)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def test_rclpy_rejects_values_out_of_range(context):
    """With the descriptors declared, rclpy rejects wrong types, ranges and read-only sets."""
    node = rclpy.create_node('sik_params_test', context=context, enable_rosout=False,
                             start_parameter_services=False)
    try:
        node.declare_parameters('', params.declarations())
        for name, value in (('num_solutions', 0), ('max_solutions_cap', 1025),
                            ('position_tolerance', -1.0), ('orientation_tolerance', math.nan),
                            ('timeout', 61.0), ('num_solutions', 'many'),
                            ('model_dir', '/elsewhere'), ('solver_processes', 2)):
            [result] = node.set_parameters([Parameter(name, value=value)])
            assert not result.successful and result.reason, (name, value)
        [result] = node.set_parameters([Parameter('timeout', value=60.0)])
        assert result.successful, result.reason
        described = node.describe_parameter('timeout')
        assert described.floating_point_range[0].to_value == 60.0
    finally:
        node.destroy_node()


def test_rclpy_rejects_an_override_out_of_range(context):
    """A start-up value out of range fails the declaration (sik_node reports bad parameters)."""
    node = rclpy.create_node('sik_params_test', context=context, enable_rosout=False,
                             start_parameter_services=False,
                             parameter_overrides=[Parameter('timeout', value=-1.0)])
    try:
        with pytest.raises(InvalidParameterValueException, match='timeout'):
            node.declare_parameters('', params.declarations())
    finally:
        node.destroy_node()
