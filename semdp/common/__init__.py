"""Pieces shared by the RL algorithms: advantages, Lagrange multipliers, networks, buffers,
observation normalisation, seeding, run-directory logging and checkpoints."""
