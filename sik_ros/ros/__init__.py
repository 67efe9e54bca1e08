"""The ROS 2 layer of sik_ros: the node, its parameters, message conversions, client and demo.

The only place that imports rclpy, ``rcl_interfaces``, the ``*_msgs`` packages and
``sik_interfaces``; the rest of :mod:`sik_ros` is a plain Python library.
"""
