"""silodem: 2D Discrete Element simulation of silo filling and discharge, with silo analytics."""

__version__ = "0.1.0"
