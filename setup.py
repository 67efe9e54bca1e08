"""Packaging of sik_ros: learned multi-solution inverse kinematics for ROS 2."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = 'sik_ros'

setup(
    name=PACKAGE_NAME,
    version='0.2.0',
    packages=find_packages(exclude=['test', 'test.*']),
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
    ],
    zip_safe=False,
    maintainer='sik_ros maintainers',
    maintainer_email='sik-ros@example.com',
    description='Learned multi-solution inverse kinematics: a pure Python library and an '
                'rclpy node, with pretrained artifacts for the Franka Emika Panda.',
    license='Apache-2.0',
    extras_require={
        'test': ['pytest', 'pytest-timeout', 'flake8', 'pydocstyle'],
    },
    entry_points={
        'console_scripts': [
            'sik-collect = sik_ros.cli.collect:main',
            'sik-train = sik_ros.cli.train:main',
            'sik-index = sik_ros.cli.index:main',
            'sik-solve = sik_ros.cli.solve:main',
            'sik-eval = sik_ros.cli.eval:main',
            'sik-build = sik_ros.cli.build:main',
            'sik_node = sik_ros.ros.run:main',
        ],
    },
)
