"""The DEM engine: particle state, walls, contact law, neighbour search, integration."""
