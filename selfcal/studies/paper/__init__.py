"""``selfcal paper``: the founding paper's experiment reproduced."""
