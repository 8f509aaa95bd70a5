"""Kinematics: the MCPC model, forward kinematics and the identification
Jacobian, DH tables, IK, the identification and its identifiability, alignment, planning."""
