"""Shared algebra: trigonometric canonical forms (fourier), simplification, equivalence (exact zero tests),
rigid-body kinematics (rotations, DH), numeric sweeps for figures. Imports nothing else of robosolve but
``solver.results``."""
