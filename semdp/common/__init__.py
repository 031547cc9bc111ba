"""What every algorithm shares: networks, observation normalisation, optimisers, seeding, the
vector-env stepper, the evaluation episodes of a vector env and the run-directory writers.
Pieces one algorithm family owns live beside it in :mod:`semdp.algos`."""
