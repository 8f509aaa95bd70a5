"""The commands behind ``selfcal acquire | calibrate | report | run``, and their
reports."""
