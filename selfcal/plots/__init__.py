"""Figures (matplotlib through ``plotting``) and the Rerun recording."""
