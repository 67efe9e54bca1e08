"""sik_ros: Selective Inverse Kinematics (learned multi-solution IK) for ROS 2."""

__version__ = '0.1.0'
