"""The board calibration's benchmarks (issue #29): does its predicted tool-point accuracy hold
(the Monte Carlo, :mod:`.accuracy`, one draw :mod:`.accuracy_draw`, its tables
:mod:`.accuracy_tables`) and the probes of it (:mod:`.accuracy_parts`, :mod:`.accuracy_binned`,
:mod:`.accuracy_shared`, :mod:`.noise_only`, :mod:`.compliance_reach`), the bootstrap's spread
(:mod:`.spread`), the folds' jackknife (:mod:`.jackknife_bias`) and a board seen in a field
scenario's truth (:mod:`.views`)."""
