"""What every ``selfcal`` command shares: errors -> messages and exit codes, the
log, progress, thread limits."""
