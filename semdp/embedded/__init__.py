"""The Safety-Embedded MDP at run time (thesis §3.5, Alg. 2): subgoal wrapper, perception,
follower, the low-level safety filter and the counters of where its time goes. The tools that
measure it (:mod:`semdp.evaluation`) and a run's artefacts (:mod:`semdp.reporting.semdp_run`)
live above it."""
