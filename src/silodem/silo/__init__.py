"""Silo geometries and the fill -> settle -> discharge procedure (the paper's Fig. 1)."""
