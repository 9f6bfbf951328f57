"""Kinematics of the SPM: geometry, unique forward kinematics by continuation, IK, Jacobians, link distances."""
