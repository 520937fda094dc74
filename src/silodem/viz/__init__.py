"""Visualisation: ParaView (VTK) files, animations and force-network pictures of a run.

* :mod:`silodem.viz.vtk`: the VTK files and .pvd series written while a run goes;
* :mod:`silodem.viz.animate`: ``silodem animate`` (MP4 / GIF from results.h5 ``/frames``);
* :mod:`silodem.viz.network`: :func:`force_network_png` (PNG bytes of one moment).

The submodules import matplotlib / meshio / imageio only when used.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def force_network_png(results_h5: Path | str, which: str | float = "end-of-filling",
                      **kwargs: Any) -> bytes:
    """PNG bytes of the force network at ``which``: "end-of-filling", "early-discharge",
    "late-discharge", "final" or a time [s] (see :mod:`silodem.viz.network`).  ValueError
    (one line) when the file has no frames or not that moment."""
    from silodem.viz.network import force_network_png as impl

    return impl(results_h5, which, **kwargs)


def force_network_pngs(results_h5: Path | str) -> dict[str, bytes]:
    """{view: PNG bytes} for the views end-of-filling, early-discharge, late-discharge that the
    run has.  ValueError (one line) when the file has no frames."""
    from silodem.viz.network import force_network_pngs as impl

    return impl(results_h5)


__all__ = ["force_network_png", "force_network_pngs"]
