"""The Monte Carlo of ``selfcal montecarlo`` and the plan comparison."""
