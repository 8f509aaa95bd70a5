"""Many calibrations: studies, the Monte Carlo against the Cramer-Rao bound, the
paper's reproduction, the render diagnostic."""
