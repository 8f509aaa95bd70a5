"""Scenario configuration (TOML) and defaults; the founding paper's tables."""
