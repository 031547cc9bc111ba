"""The Safety-Embedded MDP (thesis §3.5, Alg. 2): subgoal wrapper, perception, follower."""
