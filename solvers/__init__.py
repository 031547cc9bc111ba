"""solvers: CasADi NLPs and their backends (IPOPT, Levenberg-Marquardt, SCP on OSQP).

A library: imports casadi, numpy, scipy and osqp only -- never torch, Hydra or :mod:`sims`.
"""
