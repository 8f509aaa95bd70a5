"""Drift checks of a board calibration with new images (issue #29): the test and what changed.
The tracker route's check is :mod:`selfcal.calibration.tracker.drift`."""
