"""``selfcal import``: your own images, joint readings and target as a dataset folder."""
