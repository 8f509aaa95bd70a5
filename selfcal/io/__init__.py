"""The project's file formats: the dataset folder, ``calibration.json`` and ``truth.json``.

Each file is a frozen dataclass with one writer and one reader, and starts with ``format`` and
``schema_version`` (:mod:`selfcal.io.jsonfile`):

- :mod:`selfcal.io.dataset`: the dataset folder (:class:`~selfcal.io.dataset.Dataset`, the
  :class:`~selfcal.io.dataset.DatasetWriter`); :mod:`selfcal.io.dataset_info`: its ``dataset.json`` as
  :class:`~selfcal.io.dataset_info.DatasetInfo` and the folder's error
  :class:`~selfcal.io.dataset_info.DatasetError` (also importable from :mod:`selfcal.io.dataset`).
- :mod:`selfcal.io.calibration`: ``calibration.json`` as
  :class:`~selfcal.io.calibration.CalibrationResult` (blocks in :mod:`selfcal.io.calibration_blocks`).
- :mod:`selfcal.io.truth`: ``truth.json`` (simulation only) as :class:`~selfcal.io.truth.Truth`.
"""
