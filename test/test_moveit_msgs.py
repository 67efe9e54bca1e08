"""moveit_msgs and object_recognition_msgs: the same wire contract as upstream's.

The type hashes (RIHS01, REP 2011) below are upstream's: rosidl's hash generator run on the
upstream sources of moveit_msgs 2.6.0 (the Jazzy release, tag ``2.6.0`` of
github.com/moveit/moveit_msgs, identical to its ``ros2`` branch in these files) and of
object_recognition_msgs 2.0.0 (``ros2`` branch of github.com/wg-perception/object_recognition_msgs)
by the command::

    git -C moveit_msgs archive 2.6.0 msg srv package.xml | tar -x -C up/moveit_msgs
    git -C object_recognition_msgs archive ros2 msg package.xml \
        | tar -x -C up/object_recognition_msgs
    python scripts/type_hashes.py up/object_recognition_msgs:msg/ObjectType.msg \
        up/moveit_msgs:msg/AttachedCollisionObject.msg,...,srv/GetPositionIK.srv

(the files of this repository's ``moveit_msgs/``). A hash covers names, field names, types and
order (and the types they use); constants are not part of it, so they are pinned separately.
"""

import ctypes
import os
from pathlib import Path
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]

#: Upstream's type hashes (see the module docstring for how they were computed).
UPSTREAM = {
    'moveit_msgs/msg/AttachedCollisionObject':
        'RIHS01_7fdfe7951a33a857f20fc42c9ed410a38d06dd0c209ac774ecea746dc487dc41',
    'moveit_msgs/msg/BoundingVolume':
        'RIHS01_00bb0df2edac637497dedf1778d8f217187c8d9d10f41dcfccc4d8578123ef13',
    'moveit_msgs/msg/CollisionObject':
        'RIHS01_74b0acd6d56be032bf4f764b2c2633f50588b5fb2bd71e97206c59052747cf7e',
    'moveit_msgs/msg/Constraints':
        'RIHS01_71718200459ae8fecdc4f2c9631215f7eba5ff686c701a32e231ba8b11b3592b',
    'moveit_msgs/msg/JointConstraint':
        'RIHS01_4996641a8e12f5b7fde07f1cec1490324e1c4035ac5fc989ce99c9600c31e30d',
    'moveit_msgs/msg/MoveItErrorCodes':
        'RIHS01_dcda8a9950cf6dd6ac221c2c0d2509f52f136afa0403dd19beacdf07e83e4a07',
    'moveit_msgs/msg/OrientationConstraint':
        'RIHS01_7a1917ac47886eb1fc170317952198b203bb797f07270475a7bbaf692cad2871',
    'moveit_msgs/msg/PositionConstraint':
        'RIHS01_3758504dabfe337a1a660b29917e3405e5e858fdd6e9976edba04275396523df',
    'moveit_msgs/msg/PositionIKRequest':
        'RIHS01_200709be614f71f4d11d0bdd672785db28d27f7a10b516d9b961706a0c7f6d7d',
    'moveit_msgs/msg/RobotState':
        'RIHS01_7c516dc15713e545cb2836c5ca745fbdcfcc10de4855a41c83e6b4bf1afc3f83',
    'moveit_msgs/msg/VisibilityConstraint':
        'RIHS01_2b479935307de421623221520ee5d9ffab494af7f4b1945114fc7e4831856c75',
    'moveit_msgs/srv/GetPositionFK':
        'RIHS01_2f16ec361a135d84b85a29385abeb9eeb025e39c09038bd6b2826645edc7edad',
    'moveit_msgs/srv/GetPositionFK_Event':
        'RIHS01_898d4e18dd1194fefb93be620c84e39576b1f1a3c8c22a3fa6b421667a41379b',
    'moveit_msgs/srv/GetPositionFK_Request':
        'RIHS01_03282430a957ca7dd7e8a84b4f13225c39c467ec79efb77d9554e7b8d4cd6055',
    'moveit_msgs/srv/GetPositionFK_Response':
        'RIHS01_a1b88541679d04b392399fb4633adb55afaea22d3d5c38c79ad65f7cae6f4f2c',
    'moveit_msgs/srv/GetPositionIK':
        'RIHS01_054ed6f6f71a09b01b5246c5d80beb4dacc6f444f58df039849c76292933e9e3',
    'moveit_msgs/srv/GetPositionIK_Event':
        'RIHS01_539d4d7be25f32e750b5b5e430ad37b1d3fd0e4fdb52916b9ed0b922303b2b68',
    'moveit_msgs/srv/GetPositionIK_Request':
        'RIHS01_2fc6ac96ee9a8523466c443f06e7c76c47bd3e6b8698edc517ea82cf0b56e747',
    'moveit_msgs/srv/GetPositionIK_Response':
        'RIHS01_e80acd352080518d3498cc09f4dd84e0303e31128237de11d4019c8a5937b19f',
    'object_recognition_msgs/msg/ObjectType':
        'RIHS01_5eb3ee3976403366d7c50d7dbee8bec96b3bced1e752674a7194a35841632134',
}

#: Upstream's constants (moveit_msgs 2.6.0), by message.
UPSTREAM_CONSTANTS = {
    'MoveItErrorCodes': {
        'SUCCESS': 1, 'UNDEFINED': 0, 'FAILURE': 99999, 'PLANNING_FAILED': -1,
        'INVALID_MOTION_PLAN': -2, 'MOTION_PLAN_INVALIDATED_BY_ENVIRONMENT_CHANGE': -3,
        'CONTROL_FAILED': -4, 'UNABLE_TO_AQUIRE_SENSOR_DATA': -5, 'TIMED_OUT': -6,
        'PREEMPTED': -7, 'START_STATE_IN_COLLISION': -10,
        'START_STATE_VIOLATES_PATH_CONSTRAINTS': -11, 'START_STATE_INVALID': -26,
        'GOAL_IN_COLLISION': -12, 'GOAL_VIOLATES_PATH_CONSTRAINTS': -13,
        'GOAL_CONSTRAINTS_VIOLATED': -14, 'GOAL_STATE_INVALID': -27,
        'UNRECOGNIZED_GOAL_TYPE': -28, 'INVALID_GROUP_NAME': -15,
        'INVALID_GOAL_CONSTRAINTS': -16, 'INVALID_ROBOT_STATE': -17, 'INVALID_LINK_NAME': -18,
        'INVALID_OBJECT_NAME': -19, 'FRAME_TRANSFORM_FAILURE': -21,
        'COLLISION_CHECKING_UNAVAILABLE': -22, 'ROBOT_STATE_STALE': -23,
        'SENSOR_INFO_STALE': -24, 'COMMUNICATION_FAILURE': -25, 'CRASH': -29, 'ABORT': -30,
        'NO_IK_SOLUTION': -31},
    'CollisionObject': {'ADD': b'\x00', 'REMOVE': b'\x01', 'APPEND': b'\x02', 'MOVE': b'\x03'},
    'OrientationConstraint': {'XYZ_EULER_ANGLES': 0, 'ROTATION_VECTOR': 1},
    'VisibilityConstraint': {'SENSOR_Z': 0, 'SENSOR_Y': 1, 'SENSOR_X': 2},
}


class TypeHash(ctypes.Structure):
    """rosidl's ``rosidl_type_hash_t``: a version byte and 32 bytes of SHA-256."""

    _fields_ = [('version', ctypes.c_uint8), ('value', ctypes.c_uint8 * 32)]


@pytest.mark.e2e
def test_sources_hash_as_upstream():
    """The repository's interface sources give upstream's hash for every type, no more, no less."""
    env = dict(os.environ, AMENT_PREFIX_PATH=sys.prefix)
    run = subprocess.run([sys.executable, str(REPO / 'scripts' / 'type_hashes.py'),
                          'object_recognition_msgs', 'moveit_msgs'], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    ours = dict(line.split() for line in run.stdout.splitlines())
    assert len(ours) == len(UPSTREAM) == 20
    assert ours == UPSTREAM


def installed_hash(type_name: str) -> str:
    """The type hash the installed package's C library reports (what the middleware sends)."""
    from ament_index_python.packages import get_package_prefix
    package, kind, name = type_name.split('/')
    lib = Path(get_package_prefix(package)) / 'lib' / f'lib{package}__rosidl_generator_c.so'
    function = getattr(ctypes.CDLL(str(lib)), f'{package}__{kind}__{name}__get_type_hash')
    function.restype = ctypes.POINTER(TypeHash)
    function.argtypes = [ctypes.c_void_p]
    found = function(None).contents
    return f'RIHS{found.version:02d}_' + bytes(found.value).hex()


@pytest.mark.parametrize('type_name', sorted(UPSTREAM))
def test_installed_types_hash_as_upstream(type_name):
    """The installed moveit_msgs (ours or a real one) sends upstream's hash for each type."""
    assert installed_hash(type_name) == UPSTREAM[type_name]


def test_constants_as_upstream():
    """Every constant has upstream's name and value (hashes do not cover constants)."""
    import moveit_msgs.msg as msgs
    assert len(UPSTREAM_CONSTANTS) == 4
    for message, constants in UPSTREAM_CONSTANTS.items():
        cls = getattr(msgs, message)
        found = getattr(type(cls), f'_Metaclass_{message}__constants')
        assert found == constants, message
        assert all(getattr(cls, k) == v for k, v in constants.items())


def test_services_import_as_moveit_names():
    """The services' fields have upstream's names, types and order."""
    from moveit_msgs.srv import GetPositionFK, GetPositionIK
    fields = GetPositionIK.Request.get_fields_and_field_types()
    assert fields == {'ik_request': 'moveit_msgs/PositionIKRequest'}
    assert GetPositionIK.Response.get_fields_and_field_types() == {
        'solution': 'moveit_msgs/RobotState', 'error_code': 'moveit_msgs/MoveItErrorCodes'}
    assert list(GetPositionFK.Request.get_fields_and_field_types()) == [
        'header', 'fk_link_names', 'robot_state']


@pytest.mark.e2e
@pytest.mark.parametrize('package', ['object_recognition_msgs', 'moveit_msgs'])
def test_installed_package_is_not_shadowed(package, tmp_path):
    """Configured where the package is installed (here, the venv), the copy builds nothing."""
    env = dict(os.environ, AMENT_PREFIX_PATH=sys.prefix, CMAKE_PREFIX_PATH=sys.prefix)
    run = subprocess.run(['cmake', '-S', str(REPO / package), '-B', str(tmp_path / 'build'),
                          f'-DCMAKE_INSTALL_PREFIX={tmp_path / "install"}', '-Wno-dev'],
                         env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert f'{package} is installed in {Path(sys.prefix).resolve()}' in run.stdout
    install = subprocess.run(['cmake', '--install', str(tmp_path / 'build')], env=env,
                             capture_output=True, text=True, timeout=60)
    assert install.returncode == 0, install.stderr
    assert not (tmp_path / 'install').exists()
