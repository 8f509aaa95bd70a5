"""Measurement terms: each kind of measurement a calibration estimates with the rest.

- :mod:`selfcal.terms.base`: the interface (a term's residual and parameter blocks for
  :mod:`selfcal.solver`, its report and its ``calibration.json`` section);
- :mod:`selfcal.terms.tracker`: tracker positions, poses and distances of the tool;
- :mod:`selfcal.terms.registry`: the kinds this version knows.

A new kind is one new module here and one line in the registry (docs/terms.md).
"""
