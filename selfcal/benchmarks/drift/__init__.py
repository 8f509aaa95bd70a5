"""The drift check's benchmarks (``selfcal check``, issue #29): on a tracker calibration
(:mod:`.tracker`), on simulated images (:mod:`.images`, :mod:`.morning`, :mod:`.parts`,
:mod:`.whitened_level`, :mod:`.noise_reference`) and on the real calibrations' own folds
(:mod:`.folds` and the ``real_*`` modules)."""
