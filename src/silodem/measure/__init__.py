"""Measurements on a DEM silo (docs/measurements.md).  Nothing here changes a simulation.

Pure functions over arrays:

* ``coordination``  contacts per grain and the coordination number C_n (paper eq. 10);
* ``stress``        Love-Weber average stress in regions and PFC-style measurement circles,
                    porosity of a circle;
* ``wall_profiles`` normal and shear stress binned along walls, stress profiles along the
                    silo edges and across the silo, peak finding;
* ``discharge``     mass flow rate, mass flow index, flow classification;
* ``regions``       where the measurements are made (circles, junction band, switch zone);
* ``fields``        density and stress fields on a grid (box or Gaussian kernel), built on
                    ``gaussian`` (Gaussian coarse-graining of mass and contact stress).

Sampling during a run: ``recorders`` (``recorders_for(cfg)``), built on ``reading`` (one read
of a run's arrays between two steps).
"""
