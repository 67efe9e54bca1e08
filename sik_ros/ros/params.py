"""sik_node's parameters, declared once: name, type, default, description, range, read-only.

:data:`SPECS` is the single source of truth. From it derive

- :class:`NodeParams`, the frozen dataclass of parameter values (defaults as in
  ``config/panda.yaml``);
- :func:`descriptors`, the ``rcl_interfaces/ParameterDescriptor`` of each parameter, with a real
  ``integer_range`` / ``floating_point_range`` and ``read_only``, so that rclpy itself rejects
  values of the wrong type, out of range or for a read-only parameter;
- :func:`validate`, the rules a range cannot express: a bound set by another parameter
  (``num_solutions <= max_solutions_cap``), open lower bounds (``timeout > 0``: a ROS range is
  closed, so the descriptor says ``[0, 60]`` and :func:`validate` excludes 0), non-finite values
  and parameters that must not be empty.
"""

from dataclasses import dataclass, field, make_dataclass
import math
from typing import Dict, Optional, Tuple, Union

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType)

from sik_ros.solver.config import SolverConfig

Number = Union[int, float]


@dataclass(frozen=True)
class ParamSpec:
    """The declaration of one node parameter.

    Attributes:
        name: the ROS parameter name (and the :class:`NodeParams` field).
        type: ``str``, ``int``, ``float`` or ``bool``.
        default: the value when none is given (as in ``config/panda.yaml``).
        description: what it does, with units in brackets and the accepted values.
        min: lowest value (ints and floats); the descriptor's ``from_value``.
        max: highest value (ints and floats); the descriptor's ``to_value``.
        min_open: ``min`` itself is excluded (checked by :func:`validate`, not by rclpy).
        unit: unit of a float, for messages (``m``, ``rad``, ``s``).
        max_param: another parameter whose value also bounds this one from above.
        read_only: fixed at start-up (it identifies the loaded bundle or the solver processes).
    """

    name: str
    type: type
    default: Union[str, int, float, bool]
    description: str
    min: Optional[Number] = None
    max: Optional[Number] = None
    min_open: bool = False
    unit: str = ''
    max_param: str = ''
    read_only: bool = False

    @property
    def numeric(self) -> bool:
        """Whether the parameter is an int or a float (and so has a range)."""
        return self.type in (int, float)

    def constraints(self) -> str:
        """The bounds beyond the descriptor's range, as ``additional_constraints`` text."""
        rules = []
        if self.min_open:
            rules.append(f'> {self.min:g}')
        if self.max_param:
            rules.append(f'<= {self.max_param}')
        return '; '.join(rules)


#: The solver's own defaults, which the parameters that set them start from.
SOLVER_DEFAULTS = SolverConfig()
#: Most solver processes.
MAX_SOLVER_PROCESSES = 16
#: Most solutions per answer (the highest ``max_solutions_cap``).
MAX_SOLUTIONS = 1024

#: Values of ``command_format``: no command, or the message of a ros2_control controller.
COMMAND_FORMATS = ('none', 'float64_multi_array', 'joint_trajectory')

#: Every node parameter, in declaration order (the order of :class:`NodeParams`' fields).
SPECS: Tuple[ParamSpec, ...] = (
    ParamSpec('robot', str, '',
              'bundled model to load when model_dir is empty (e.g. panda); empty with '
              'model_dir empty: the arm of robot_description (the parameter, else the '
              'robot_description topic) between base_frame and tip_frame (read-only)',
              read_only=True),
    ParamSpec('model_dir', str, '',
              'bundle directory to load; empty: the bundled model of `robot` (read-only)',
              read_only=True),
    ParamSpec('base_frame', str, '',
              'frame of targets, obstacles and answers; must be the bundle\'s base; empty: '
              'the bundle\'s (read-only)',
              read_only=True),
    ParamSpec('tip_frame', str, '',
              'frame placed on the target; must be the bundle\'s tip frame; empty: the '
              'bundle\'s (read-only)',
              read_only=True),
    ParamSpec('num_solutions', int, 16,
              'solutions returned when a request asks for 0; 1..max_solutions_cap',
              min=1, max=MAX_SOLUTIONS, max_param='max_solutions_cap'),
    ParamSpec('max_solutions_cap', int, SOLVER_DEFAULTS.max_solutions_cap,
              'most solutions per answer; larger requests are clamped; 1..1024',
              min=1, max=MAX_SOLUTIONS),
    ParamSpec('position_tolerance', float, SOLVER_DEFAULTS.position_tolerance,
              'a solution is exact within this position error [m]; (0, 0.1]',
              min=0.0, max=0.1, min_open=True, unit='m'),
    ParamSpec('orientation_tolerance', float, SOLVER_DEFAULTS.orientation_tolerance,
              'and within this orientation error for pose goals [rad]; (0, pi]',
              min=0.0, max=math.pi, min_open=True, unit='rad'),
    ParamSpec('one_per_family', bool, SOLVER_DEFAULTS.one_per_family,
              'answer at most one solution per posture family (the best of each)'),
    ParamSpec('refine', bool, True,
              'refine decoded solutions numerically (false: raw network output)'),
    ParamSpec('timeout', float, 0.05,
              'time budget of a request whose timeout is 0 [s]; (0, 60]',
              min=0.0, max=60.0, min_open=True, unit='s'),
    ParamSpec('path_timeout', float, 2.0,
              'time budget of a solve_path request whose timeout is 0 [s]; (0, 600]',
              min=0.0, max=600.0, min_open=True, unit='s'),
    ParamSpec('use_joint_states', bool, False,
              'seed requests that have no seed with the latest joint_states'),
    ParamSpec('goal_use_orientation', bool, False,
              '~/goal poses are pose goals (false: position goals)'),
    ParamSpec('publish_markers', bool, True,
              'publish the ranked postures on ~/markers for RViz'),
    ParamSpec('goal_num_solutions', int, 1,
              'solutions in each answer to a ~/goal (a stream: 1, the one nearest the seed); '
              '1..max_solutions_cap',
              min=1, max=MAX_SOLUTIONS, max_param='max_solutions_cap'),
    ParamSpec('goal_timeout', float, 0.02,
              'time budget of each ~/goal [s]; (0, 60]',
              min=0.0, max=60.0, min_open=True, unit='s'),
    ParamSpec('goal_max_joint_step', float, 0.5,
              'a ~/goal answer whose best solution is farther than this from the seed (the '
              'previous answer or joint_states) in any joint is a jump: answered JOINT_JUMP, '
              'not followed and not commanded [rad]; 0: no bound; [0, 10]',
              min=0.0, max=10.0, unit='rad'),
    ParamSpec('goal_marker_rate', float, 10.0,
              'most ~/markers messages per second for ~/goal answers [Hz]; 0: none; [0, 1000]',
              min=0.0, max=1000.0, unit='Hz'),
    ParamSpec('command_format', str, 'none',
              'command output for ros2_control of each ~/goal answer: none, '
              'float64_multi_array (forward_command_controller) or joint_trajectory '
              '(joint_trajectory_controller) (read-only)',
              read_only=True),
    ParamSpec('command_topic', str, '~/command',
              'topic of the command output, e.g. /forward_position_controller/commands '
              '(read-only)',
              read_only=True),
    ParamSpec('solver_processes', int, 0,
              'solver processes serving requests in parallel (beyond the GIL); 0: solve in the '
              'executor threads; 0..16 (read-only)',
              min=0, max=MAX_SOLVER_PROCESSES, read_only=True),
    ParamSpec('goal_solver_process', bool, False,
              'solve ~/goal in a solver process of its own, so that a goal stream does not '
              'hold the GIL the services solve under (the node\'s own solver stands in while '
              'that process cannot serve); an arm served from its table of configurations '
              'solves its stream in the node (read-only)',
              read_only=True),
    ParamSpec('max_obstacles', int, SOLVER_DEFAULTS.max_obstacles,
              'most obstacles a request may give (more: INVALID_GOAL); 0..10000',
              min=0, max=10000),
    ParamSpec('max_waypoints', int, SOLVER_DEFAULTS.max_waypoints,
              'most waypoints a solve_path request may give (more: INVALID_GOAL); 1..100000',
              min=1, max=100000),
    ParamSpec('max_batch_targets', int, 1000,
              'most targets a solve_ik_batch request may give (more: INVALID_GOAL, nothing '
              'solved); 1..100000',
              min=1, max=100000),
    ParamSpec('shutdown_grace', float, 1.0,
              'on SIGINT/SIGTERM, time in-flight requests get to finish before the node exits '
              '(new ones are answered TIMEOUT) [s]; (0, 60]',
              min=0.0, max=60.0, min_open=True, unit='s'),
    ParamSpec('robot_description', str, '',
              'the robot\'s URDF (as robot_state_publisher holds it). With robot and '
              'model_dir empty, the node serves its chain base_frame -> tip_frame (empty: it '
              'waits for the robot_description topic, and follows it); with a bundle named, '
              'a bundle whose chain differs from it is refused (read-only)',
              read_only=True),
    ParamSpec('learning', bool, True,
              'an arm from robot_description: learn its model in the background (one core, '
              'low priority) and serve it once built, cached per arm; false: the table of '
              'configurations only (a cached model is still served) (read-only)',
              read_only=True),
    ParamSpec('learning_time', float, 1800.0,
              'the background build\'s budget [s] (sik-build --time); [30, 86400]',
              min=30.0, max=86400.0, unit='s', read_only=True),
    ParamSpec('learning_rows', int, 3_000_000,
              'configurations the background build collects (sik-build --rows); '
              '10000..20000000', min=10_000, max=20_000_000, read_only=True),
    ParamSpec('cache_dir', str, '',
              'folder of the per-arm cache (an arm\'s entry: <cache_dir>/sik_ros/...); empty: '
              '$XDG_CACHE_HOME, else ~/.cache (read-only)',
              read_only=True),
    ParamSpec('sweep_time', float, 3.0,
              'time the table of configurations of a new arm may take [s]; [0.2, 60]',
              min=0.2, max=60.0, unit='s', read_only=True),
    ParamSpec('moveit_services', bool, True,
              'serve MoveIt\'s kinematics services (compute_ik_service, compute_fk_service); '
              'false where move_group offers them beside the node (read-only)',
              read_only=True),
    ParamSpec('compute_ik_service', str, '/compute_ik',
              'name of the moveit_msgs/srv/GetPositionIK service (read-only)', read_only=True),
    ParamSpec('compute_fk_service', str, '/compute_fk',
              'name of the moveit_msgs/srv/GetPositionFK service (read-only)', read_only=True),
    ParamSpec('ik_group', str, '',
              'the group_name compute_ik answers (MoveIt\'s planning group of the arm); empty: '
              'the bundle\'s robot name followed by _arm (panda_arm for the Panda)'),
    ParamSpec('lifecycle', bool, False,
              'a managed node (rclpy LifecycleNode): it starts unconfigured, loads the bundle '
              'on configure and serves only while active (otherwise requests are answered '
              'TIMEOUT with the state); false: it loads and serves at start-up (read-only)',
              read_only=True),
)
#: The declarations by name.
SPEC: Dict[str, ParamSpec] = {s.name: s for s in SPECS}
#: Parameter descriptions; read-only ones identify the loaded bundle (change them by restarting).
DESCRIPTIONS: Dict[str, str] = {s.name: s.description for s in SPECS}
READ_ONLY: Tuple[str, ...] = tuple(s.name for s in SPECS if s.read_only)

NodeParams = make_dataclass(
    'NodeParams', [(s.name, s.type, field(default=s.default)) for s in SPECS], frozen=True)
NodeParams.__module__ = __name__
NodeParams.__doc__ = '\n'.join(
    ['The node\'s parameters (defaults as in ``config/panda.yaml``), made from :data:`SPECS`.',
     '', 'Attributes:'] + [f'    {s.name}: {s.description}.' for s in SPECS])

_ROS_TYPES = {str: ParameterType.PARAMETER_STRING, int: ParameterType.PARAMETER_INTEGER,
              float: ParameterType.PARAMETER_DOUBLE, bool: ParameterType.PARAMETER_BOOL}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS descriptor of one parameter: type, description, range, read-only."""
    d = ParameterDescriptor(name=spec.name, type=_ROS_TYPES[spec.type],
                            description=spec.description,
                            additional_constraints=spec.constraints(),
                            read_only=spec.read_only)
    if spec.type is int:
        d.integer_range = [IntegerRange(from_value=int(spec.min), to_value=int(spec.max),
                                        step=1)]
    elif spec.type is float:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.min),
                                                     to_value=float(spec.max), step=0.0)]
    return d


def descriptors() -> Dict[str, ParameterDescriptor]:
    """Descriptor of every parameter, by name (a fresh one each call: rclpy modifies them)."""
    return {s.name: descriptor(s) for s in SPECS}


def declarations(defaults: Optional['NodeParams'] = None) -> list:
    """``(name, default, descriptor)`` of every parameter, for ``Node.declare_parameters``."""
    defaults = defaults if defaults is not None else NodeParams()
    return [(s.name, getattr(defaults, s.name), descriptor(s)) for s in SPECS]


def markdown_table() -> str:
    """Every parameter as a Markdown table: name, type, default, range, read-only, description.

    docs/interfaces.md holds it between ``<!-- begin: parameters -->`` and ``<!-- end:
    parameters -->`` (written by ``scripts/params_table.py``, checked by the tests).
    """
    rows = ['| parameter | type | default | range | read-only | description |',
            '|---|---|---|---|---|---|']
    for s in SPECS:
        default = f"'{s.default}'" if s.type is str else (
            str(s.default).lower() if s.type is bool else f'{s.default:g}' if s.type is float
            else f'{s.default:,}')
        span = _range_text(s, s.max) if s.numeric else ''
        if s.max_param:
            span += f', <= {s.max_param}'
        text = s.description.replace('|', '\\|')
        rows.append(f'| `{s.name}` | {s.type.__name__} | `{default}` | {span} | '
                    f'{"yes" if s.read_only else ""} | {text} |')
    return '\n'.join(rows) + '\n'


def _range_text(spec: ParamSpec, upper: Number) -> str:
    if spec.type is int:
        return f'{spec.min}..{upper}'
    return f'{"(" if spec.min_open else "["}{spec.min:g}, {upper:g}] {spec.unit}'.rstrip()


def _check_range(spec: ParamSpec, value: Number, p: 'NodeParams') -> Optional[str]:
    upper = spec.max
    if spec.max_param:
        upper = min(upper, getattr(p, spec.max_param))
        limits = f'{spec.min}..{spec.max_param} ({getattr(p, spec.max_param)})'
    else:
        limits = _range_text(spec, upper)
    low_ok = value > spec.min if spec.min_open else value >= spec.min
    if not (math.isfinite(value) and low_ok and value <= upper):
        return f'{spec.name} must be in {limits}; got {value}'
    return None


def validate(p: 'NodeParams') -> Optional[str]:
    """Why a set of parameter values is unusable, or None if it is fine.

    Checks what no descriptor can (non-empty strings, bounds set by another parameter, open
    lower bounds, non-finite values) and, again, the ranges of :data:`SPECS` (rclpy checks those
    one parameter at a time), so that a whole set of values is checked at once.
    """
    if not p.robot and not p.model_dir and p.robot_description and not (
            p.base_frame and p.tip_frame):
        return ('an arm from robot_description needs base_frame and tip_frame (the chain to '
                'serve)')
    if p.command_format not in COMMAND_FORMATS:
        return (f'command_format must be one of {", ".join(COMMAND_FORMATS)}; '
                f'got {p.command_format!r}')
    if p.command_format != 'none' and not p.command_topic:
        return 'command_topic is empty: name the controller\'s command topic'
    if p.moveit_services and not (p.compute_ik_service and p.compute_fk_service):
        return 'compute_ik_service and compute_fk_service must not be empty (or set ' \
            'moveit_services to false)'
    # ints before floats; a number bounded by another parameter after that parameter
    for s in sorted((s for s in SPECS if s.numeric),
                    key=lambda s: (s.type is float, bool(s.max_param))):
        reason = _check_range(s, getattr(p, s.name), p)
        if reason is not None:
            return reason
    return None
