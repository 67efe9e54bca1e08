"""``sik-view``: a browser viewer of the ranked solutions (viser; no ROS needed).

:mod:`~sik_ros.viewer.meshes` poses the arm's URDF geometry, :mod:`~sik_ros.viewer.scene`
computes what to show for a target, :mod:`~sik_ros.viewer.app` serves it.
"""
