"""The ``selfcal`` command: the parser and the commands' entry points."""
