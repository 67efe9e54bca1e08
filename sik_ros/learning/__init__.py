"""The learned models: SIK and PSIK, their baselines, training and checkpoints.

:mod:`.models` defines the networks, :mod:`.training` and :mod:`.training_data` train them,
:mod:`.checkpoints` saves and validates them, and :mod:`.indexing` encodes a dataset with a
trained encoder into an index table. Inference loads checkpoints without importing the trainer.
"""
