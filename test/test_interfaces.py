"""The built sik_interfaces package matches the contract (docs/interfaces.md, section 4)."""

import math

import pytest

try:
    from sik_interfaces.msg import IKSolution, IKSolutionArray
    from sik_interfaces.srv import SolveIK
except ImportError as exc:  # pragma: no cover - only without `make setup`
    pytest.fail(
        f'sik_interfaces is not built into this Python environment ({exc}); run `make setup`',
        pytrace=False,
    )

SOLVE_IK_REQUEST_FIELDS = {
    'target': 'geometry_msgs/PoseStamped',
    'use_orientation': 'boolean',
    'max_solutions': 'uint32',
    'seed': 'sensor_msgs/JointState',
    'obstacles': 'sequence<shape_msgs/SolidPrimitive>',
    'obstacle_poses': 'sequence<geometry_msgs/Pose>',
    'timeout': 'builtin_interfaces/Duration',
}
SOLVE_IK_RESPONSE_FIELDS = {
    'error_code': 'int32',
    'message': 'string',
    'num_families': 'uint32',
    'solutions': 'sequence<sik_interfaces/IKSolution>',
}
IK_SOLUTION_FIELDS = {
    'joint_state': 'sensor_msgs/JointState',
    'posture_index': 'sequence<float>',
    'position_error': 'double',
    'orientation_error': 'double',
    'min_obstacle_distance': 'double',
    'self_collision': 'boolean',
    'score': 'double',
    'tier': 'uint8',
    'family': 'uint16',
}
IK_SOLUTION_ARRAY_FIELDS = {
    'header': 'std_msgs/Header',
    'error_code': 'int32',
    'message': 'string',
    'num_families': 'uint32',
    'goals_replaced': 'uint32',
    'joint_step': 'double',
    'solutions': 'sequence<sik_interfaces/IKSolution>',
}
ERROR_CODES = {
    'SUCCESS': 1,
    'NO_SOLUTION': -1,
    'INVALID_GOAL': -2,
    'INVALID_FRAME': -3,
    'INVALID_SEED': -4,
    'TIMEOUT': -5,
    'ROBOT_MISMATCH': -6,
    'JOINT_JUMP': -7,
    'INTERNAL_ERROR': -99,
}


def test_installed_package_is_the_generated_one():
    """The import resolves to the generated Python package, not the source folder."""
    import sik_interfaces

    assert sik_interfaces.__file__ is not None, (
        'sik_interfaces resolved to the source folder (a namespace package): not built')


@pytest.mark.parametrize('msg_type, expected', [
    (SolveIK.Request, SOLVE_IK_REQUEST_FIELDS),
    (SolveIK.Response, SOLVE_IK_RESPONSE_FIELDS),
    (IKSolution, IK_SOLUTION_FIELDS),
    (IKSolutionArray, IK_SOLUTION_ARRAY_FIELDS),
], ids=['SolveIK.Request', 'SolveIK.Response', 'IKSolution', 'IKSolutionArray'])
def test_fields_match_the_contract(msg_type, expected):
    """Each message has exactly the contract's fields, in order, with the contract's types."""
    assert list(msg_type.get_fields_and_field_types().items()) == list(expected.items())


@pytest.mark.parametrize('name, value', sorted(ERROR_CODES.items()))
def test_error_code_constants(name, value):
    """The SolveIK response carries the contract's error codes with their values."""
    assert getattr(SolveIK.Response, name) == value


def test_error_codes_are_distinct_and_only_success_is_positive():
    """No two codes share a value, and only SUCCESS is positive (moveit_msgs convention)."""
    values = [getattr(SolveIK.Response, name) for name in ERROR_CODES]
    assert len(set(values)) == len(values)
    assert [v > 0 for v in values].count(True) == 1


def test_defaults_mean_node_defaults():
    """A default request asks for the node's defaults: no orientation, count and timeout 0."""
    request = SolveIK.Request()
    assert request.use_orientation is False
    assert request.max_solutions == 0
    assert (request.timeout.sec, request.timeout.nanosec) == (0, 0)
    assert request.target.header.frame_id == ''
    assert list(request.seed.name) == [] and list(request.seed.position) == []
    assert list(request.obstacles) == [] and list(request.obstacle_poses) == []


def test_solution_array_round_trips_through_serialization():
    """A filled IKSolutionArray survives CDR serialization (the C type support is built)."""
    from rclpy.serialization import deserialize_message, serialize_message

    solution = IKSolution()
    solution.joint_state.name = [f'panda_joint{i}' for i in range(1, 8)]
    solution.joint_state.position = [0.1 * i for i in range(7)]
    solution.posture_index = [0.25, -0.5]
    solution.position_error = 1e-4
    solution.orientation_error = 2e-3
    solution.min_obstacle_distance = math.inf
    solution.score = 0.125
    solution.family = 3
    message = IKSolutionArray()
    message.header.frame_id = 'panda_link0'
    message.error_code = SolveIK.Response.SUCCESS
    message.message = 'ok'
    message.solutions = [solution, IKSolution()]

    back = deserialize_message(serialize_message(message), IKSolutionArray)
    assert back == message
    assert math.isinf(back.solutions[0].min_obstacle_distance)
    assert list(back.solutions[0].posture_index) == [0.25, -0.5]
    assert back.solutions[0].family == 3 and IKSolution.NO_FAMILY == 65535


def test_request_round_trips_through_serialization():
    """A SolveIK request with obstacles and a seed survives CDR serialization."""
    from rclpy.serialization import deserialize_message, serialize_message
    from geometry_msgs.msg import Pose
    from shape_msgs.msg import SolidPrimitive

    request = SolveIK.Request()
    request.target.header.frame_id = 'panda_link0'
    request.target.pose.position.x = 0.3
    request.use_orientation = True
    request.max_solutions = 8
    request.seed.name = ['panda_joint1']
    request.seed.position = [0.5]
    box = SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[0.1, 0.2, 0.3])
    request.obstacles = [box]
    request.obstacle_poses = [Pose()]
    request.timeout.nanosec = 50_000_000

    back = deserialize_message(serialize_message(request), SolveIK.Request)
    assert back == request
