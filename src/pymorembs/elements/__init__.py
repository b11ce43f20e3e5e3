"""Finite elements used to build models and couplings: 3-D beams, rigid bodies."""
