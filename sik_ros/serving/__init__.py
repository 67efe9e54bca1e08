"""Serving many requests: solver processes and the node's solvers, without ROS.

:mod:`.pool` runs :class:`~sik_ros.solver.SelectiveIK` in solver processes; :mod:`.solvers`
gives the node one :class:`~sik_ros.serving.solvers.Solver` to call, local or pooled.
"""
