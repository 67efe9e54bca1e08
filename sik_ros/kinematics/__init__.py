"""The arm: its chain, forward kinematics, collision geometry and joint conventions.

The first floor of the library. :mod:`.robot` wraps a Pinocchio model (FK, Jacobians, limits),
:mod:`.robots` loads arms from example-robot-data or a URDF, :mod:`.chain` is the same chain as
plain arrays (NumPy or torch), :mod:`.collision` holds obstacles and self-collision, and
:mod:`.rotations`, :mod:`.goal_error` and :mod:`.periodic` the shared conventions.
"""
