"""Tables built from the arm's joint-space sweep: the dataset and what the solver looks up.

:mod:`.dataset` is Algorithm 1 of the paper (the sweep and its FK), :mod:`.index_table` the
posture-index table (KD-tree + dictionary), :mod:`.seed_table` the start table for pose goals,
and :mod:`.prior_table`, :mod:`.reach_grid` and :mod:`.point_sets` their parts.
"""
