"""Flange poses at the file edge: the robots' orientation conventions (:mod:`.conventions`), pose
files a user gives (:mod:`.files`) and the pose dataset folder ``selfcal import --poses`` writes
(:mod:`.dataset`)."""
