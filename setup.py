"""Packaging of sik_ros: learned multi-solution inverse kinematics for ROS 2."""

import filecmp
from glob import glob
import os
import subprocess
import sys

from setuptools import find_namespace_packages, setup
from setuptools.command.develop import develop
from setuptools.command.install import install

PACKAGE_NAME = 'sik_ros'
HERE = os.path.dirname(os.path.abspath(__file__))
INTERFACES = 'sik_interfaces'


def _interfaces_prefix():
    """The first prefix on AMENT_PREFIX_PATH that holds sik_interfaces, else None."""
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        marker = os.path.join(prefix, 'share', 'ament_index', 'resource_index', 'packages',
                              INTERFACES)
        if prefix and os.path.isfile(marker):
            return prefix
    return None


def _differing_definition(prefix):
    """The first message or service file of this source that ``prefix`` lacks or has changed."""
    for source in sorted(glob(os.path.join(HERE, INTERFACES, '*', '*.*'))):
        kind, name = source.split(os.sep)[-2:]
        if kind not in ('msg', 'srv'):
            continue
        built = os.path.join(prefix, 'share', INTERFACES, kind, name)
        if not os.path.isfile(built) or not filecmp.cmp(source, built, shallow=False):
            return f'{kind}/{name}'
    return None


def _workspace_path(command):
    """This package's folder relative to the colcon workspace (``<ws>/build/sik_ros/build``)."""
    build_base = os.path.abspath(command.get_finalized_command('build').build_base)
    package_build = os.path.dirname(build_base)
    if os.path.basename(os.path.dirname(package_build)) == 'build':
        return os.path.relpath(HERE, os.path.dirname(os.path.dirname(package_build)))
    return HERE


def check_interfaces(command):
    """In a colcon build, stop unless the sik_interfaces of this source is built or sourced.

    colcon does not look for packages inside another package's folder, so a plain
    ``colcon build`` finds sik_ros but not sik_interfaces/ within it; the node would then fail at
    run time for want of its messages. Outside colcon (pip) nothing is checked.
    """
    if os.environ.get('COLCON') != '1':
        return
    prefix = _interfaces_prefix()
    if prefix is not None:
        changed = _differing_definition(prefix)
        if changed is None:
            return
        reason = (f'the {INTERFACES} found in {prefix} was built from other definitions '
                  f'({changed} differs from this source)')
    else:
        reason = (f'{INTERFACES} is neither in this build nor on AMENT_PREFIX_PATH: it sits '
                  f'in {INTERFACES}/ inside this package, where colcon does not look')
    path = _workspace_path(command)
    raise SystemExit(
        f'sik_ros: {reason}. Build both packages:\n'
        f'    colcon build --paths {path} {os.path.join(path, INTERFACES)}\n'
        'with ROS 2 sourced (source /opt/ros/jazzy/setup.bash; in the sik_ros venv: '
        'source scripts/env.sh).')


def compile_kernels(path):
    """Compile the numba kernels of the sik_ros under ``path`` into their disk cache.

    numba keys its cache on each source file's path, so this runs against the installed copy.
    A failure leaves the kernels to be compiled at first use (a warning, not an error).
    """
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (path, os.environ.get('PYTHONPATH', '')) if p))
    done = subprocess.run([sys.executable, '-m', 'sik_ros.kernels'], cwd=path, env=env,
                          check=False)
    if done.returncode != 0:
        print('sik_ros: warning: the kernels were not compiled ahead of use; the first solve '
              'compiles them', file=sys.stderr)


class ColconInstall(install):
    """``install`` that checks for sik_interfaces first when colcon runs it."""

    def run(self):
        check_interfaces(self)
        super().run()
        if os.environ.get('COLCON') == '1':
            compile_kernels(os.path.abspath(self.install_lib))


class ColconDevelop(develop):
    """``develop`` (colcon's --symlink-install) with the same check."""

    def run(self):
        check_interfaces(self)
        super().run()
        if os.environ.get('COLCON') == '1':
            compile_kernels(HERE)


setup(
    name=PACKAGE_NAME,
    version='0.9.0',
    # namespace packages too, so that the bundled model's folders install as package data
    packages=find_namespace_packages(include=[PACKAGE_NAME, PACKAGE_NAME + '.*']),
    package_data={
        PACKAGE_NAME: [
            'bundles/panda/*',
            'bundles/panda/**/*',
        ],
    },
    include_package_data=True,
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE_NAME]),
        ('share/' + PACKAGE_NAME, ['package.xml']),
        ('share/' + PACKAGE_NAME + '/config', glob('config/*.yaml')),
    ],
    python_requires='>=3.10',
    install_requires=[
        'setuptools',
        'numpy',
        'scipy',
        'pin',
        'example-robot-data-loaders',
        'torch',
        'tqdm',
        'threadpoolctl',
        'matplotlib',
        'PyYAML',
        'xacro',
        'viser',
    ],
    zip_safe=False,
    maintainer='sik_ros maintainers',
    maintainer_email='sik-ros@example.com',
    description='Learned multi-solution inverse kinematics: a pure Python library and an '
                'rclpy node, with pretrained artifacts for the Franka Emika Panda.',
    license='Apache-2.0',
    extras_require={
        'test': ['pytest', 'pytest-timeout', 'flake8', 'pydocstyle'],
        'ray': ['ray==2.60.0'],
    },
    cmdclass={'install': ColconInstall, 'develop': ColconDevelop},
    entry_points={
        'console_scripts': [
            'sik-collect = sik_ros.cli.collect:main',
            'sik-train = sik_ros.cli.train:main',
            'sik-index = sik_ros.cli.index:main',
            'sik-solve = sik_ros.cli.solve:main',
            'sik-reach = sik_ros.cli.reach:main',
            'sik-eval = sik_ros.cli.eval:main',
            'sik-build = sik_ros.cli.build:main',
            'sik-chain = sik_ros.cli.chain:main',
            'sik-view = sik_ros.cli.view:main',
            'sik_node = sik_ros.ros.run:main',
        ],
    },
)
