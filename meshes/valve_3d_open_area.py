"""The geometric orifice area of the 3D valve sector at rest, independently of fdfsi: the analytic
leaflet surface of make_valve_3d.py (its ventricular face, gamma_s), sampled on 400 x 400
quadrilaterals and projected along the axis, subtracted (shapely's polygon union and
intersection) from the exact annulus sector r < 12.5, 0 <= theta <= 60 degrees at z = 0, times 6
for the whole valve. tests/cases.rs (`valve_3d_sector_opens_on_its_symmetry_planes`) holds
fdfsi's `open_area` at rest (the faceted fluid section less the Q2 leaflet's facets,
rasterised) to this value.

Run: python valve_3d_open_area.py   (needs `gmsh` and `shapely` from PyPI)
"""
import math

from shapely.geometry import Polygon
from shapely.ops import unary_union

import make_valve_3d as m


def open_area(n=400):
    arc = [(m.R_A * math.cos(t), m.R_A * math.sin(t)) for t in (m.SECTOR * k / 2000 for k in range(2001))]
    sector = Polygon([(0.0, 0.0)] + arc)

    def projected(i, j):
        s = i / n
        xi0 = m.band_start(s)
        x = m.mid_surface(s, xi0 + (1.0 - xi0) * j / n)
        return (x[0], x[1])

    pts = [[projected(i, j) for j in range(n + 1)] for i in range(n + 1)]
    quads = [Polygon([pts[i][j], pts[i + 1][j], pts[i + 1][j + 1], pts[i][j + 1]]) for i in range(n) for j in range(n)]
    cover = unary_union([q for q in quads if q.is_valid and q.area > 0.0])
    return 6.0 * (sector.area - sector.intersection(cover).area)


if __name__ == "__main__":
    print(f"open area at rest, whole valve: {open_area():.3f} mm^2")
