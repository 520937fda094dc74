"""Grain sizes: the radius distributions a config may choose, drawn from the run's seed, and
their moments, which the checks and measurements use before a single grain exists.

``material.radius_distribution``:

- ``"uniform"`` (default; the paper's Tables 1-2): the radius r is uniform in
  [r_min, r_max], with probability density p(r) = 1 / (r_max - r_min).
- ``"uniform_mass"``: every radius interval of one width holds the same mass of grains, the
  grading (sieve) curve of a silo engineer, linear in r. A disk's mass grows as r^2, so
  p(r) = r_min r_max / ((r_max - r_min) r^2): more small grains than large ones. Its inverse
  distribution function, 1/r = 1/r_min - u (1/r_min - 1/r_max) for u uniform in [0, 1], draws it.
- ``"discrete"``: the radii ``material.radii`` with the shares by number
  ``material.radius_shares`` (equal shares when unset), e.g. a binary mixture. The counts are
  exact, not drawn: round(share x N) by largest remainder, the order shuffled by the seed.

Moments (mean radius <r> and mean square radius <r^2>, by number), from the densities above:
uniform <r> = (a + b)/2 and <r^2> = (b^3 - a^3) / (3 (b - a)); uniform_mass
<r> = a b ln(b/a) / (b - a) and <r^2> = a b; discrete <r> = sum s_i r_i, <r^2> = sum s_i r_i^2
(a = r_min, b = r_max).
"""

from __future__ import annotations

import math

import numpy as np

from silodem.config import Material


def draw_radii(material: Material, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` grain radii [m] of ``material``'s distribution, drawn from ``rng``. The uniform
    distribution takes one ``rng.uniform`` call, as every run before the other distributions
    existed did, so a config's grains stay the same."""
    a, b = material.radius_min, material.radius_max
    kind = material.radius_distribution
    if kind == "uniform":
        return rng.uniform(a, b, n)
    if kind == "uniform_mass":
        u = rng.uniform(0.0, 1.0, n)  # (drawn for one size too: the same random stream)
        if b == a:  # (1 / (1 / a) is not always a in floating point)
            return np.full(n, a)
        return 1.0 / (1.0 / a - u * (1.0 / a - 1.0 / b))
    counts = discrete_counts(shares(material), n)
    return rng.permutation(np.repeat(np.asarray(material.radii, dtype=float), counts))


def shares(material: Material) -> np.ndarray:
    """The shares by number of ``material.radii`` (equal when ``radius_shares`` is unset)."""
    if material.radius_shares is not None:
        return np.asarray(material.radius_shares, dtype=float)
    n = len(material.radii or ())
    return np.full(n, 1.0 / n) if n else np.zeros(0)


def discrete_counts(share: np.ndarray, n: int) -> np.ndarray:
    """Grain counts of each size that sum to ``n`` and lie within one of ``share x n``: the
    floors, then one more for the largest remainders (ties to the first size)."""
    exact = np.asarray(share, dtype=float) * n / float(np.sum(share))
    counts = np.floor(exact).astype(np.int64)
    short = n - int(counts.sum())
    order = np.argsort(-(exact - counts), kind="stable")
    counts[order[:short]] += 1
    return counts


def mean_radius(material: Material) -> float:
    """The mean grain radius <r> by number [m] (module docstring)."""
    a, b = material.radius_min, material.radius_max
    if material.radius_distribution == "discrete":
        return float(np.dot(shares(material), material.radii))
    if b == a:
        return a
    if material.radius_distribution == "uniform_mass":
        return a * b * math.log(b / a) / (b - a)
    return 0.5 * (a + b)


def mean_square_radius(material: Material) -> float:
    """The mean square grain radius <r^2> by number [m^2] (module docstring): a grain's
    mean area is pi <r^2>."""
    a, b = material.radius_min, material.radius_max
    if material.radius_distribution == "discrete":
        return float(np.dot(shares(material), np.square(material.radii)))
    if b == a:
        return a * a
    if material.radius_distribution == "uniform_mass":
        return a * b
    return (b**3 - a**3) / (3.0 * (b - a))


def describe(material: Material) -> str:
    """The size distribution in words, radii in metres: "uniform in [0.09, 0.11]",
    "equal mass per radius interval in [0.09, 0.11]" or "0.08 (25 %), 0.12 (75 %)"."""
    a, b = material.radius_min, material.radius_max
    if material.radius_distribution == "discrete":
        return ", ".join(f"{r:.4g} ({100 * s:.3g} %)"
                         for r, s in zip(material.radii or (), shares(material), strict=True))
    if material.radius_distribution == "uniform_mass":
        return f"equal mass per radius interval in [{a:.4g}, {b:.4g}]"
    return f"uniform in [{a:.4g}, {b:.4g}]"
