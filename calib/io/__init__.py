"""The project's file formats: the dataset folder, ``calibration.json`` and ``truth.json``.

Each file is a frozen dataclass with one writer and one reader, and starts with ``format`` and
``schema_version`` (:mod:`calib.io.jsonfile`):

- :mod:`calib.io.dataset`: the dataset folder (:class:`~calib.io.dataset.Dataset`, the
  :class:`~calib.io.dataset.DatasetWriter`); :mod:`calib.io.dataset_info`: its ``dataset.json`` as
  :class:`~calib.io.dataset_info.DatasetInfo` and the folder's error
  :class:`~calib.io.dataset_info.DatasetError` (also importable from :mod:`calib.io.dataset`).
- :mod:`calib.io.calibration`: ``calibration.json`` as
  :class:`~calib.io.calibration.CalibrationResult` (blocks in :mod:`calib.io.calibration_blocks`).
- :mod:`calib.io.truth`: ``truth.json`` (simulation only) as :class:`~calib.io.truth.Truth`.
"""
