"""The calibration routes: the field self-calibration (``field``), a board of
known geometry (``board``), tracker measurements (``tracker``), and the checks they share."""
