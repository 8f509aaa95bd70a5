"""The tracker calibration's benchmarks: the identification against pybotics (:mod:`.compare`,
``python -m selfcal.benchmarks.tracker``; pybotics' side in its own environment:
:mod:`.pybotics_fit`), whether its predicted tool-point accuracy holds (:mod:`.accuracy`,
:mod:`.accuracy_growth`), its k-fold held-out RMS against the fair nominal's (:mod:`.held_out`)
and the simulated tracker sets they use (:mod:`.sim`)."""
