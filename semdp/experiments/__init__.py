"""Helpers of the experiment presets (conf/experiment/): evaluation of trained runs under
changed settings -- the eps' trade-off (thesis Fig. B.1) and the simulated transfer (Table 3.2)."""
