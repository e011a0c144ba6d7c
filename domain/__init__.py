"""Domain geometry: the free space and obstacles inside the rectangle Omega, at the geometry's own resolution.

Modules, one concept each:

``domain``    :class:`Domain`: the fine raster or polygons, ``contains``, the robots' reflection at obstacles
``cells``     planner cells over the fine geometry (exact free-area fractions, connectivity)
``edges``     boundary edges and the index of the first edge a step crosses
``walls``     mirror reflection at the walls of the rectangle
``kernel``    the obstacle reflection in compiled C (bit for bit the NumPy code)
``geodesic``  geodesic distances between planner cells (:class:`GeodesicGrid`)
``spectrum``  eigenfunctions of the Neumann Laplacian on the free cells, walls removed (:func:`neumann_modes`)
``builtin``   the built-in maps (``harbour``, ``floor``, ``lake``)
``loaders``   domain files (.npz, .png, .tif, .geojson, ROS .yaml) and :func:`make_domain`
``limits``    how large a domain file may be (pixels, vertices, nesting) before it is refused
``units``     the units of a map's coordinate system: the EPSG projected CRSs not in metres (feet), refused
``settings``  the ``[domain]`` table of a configuration (:class:`DomainSettings`)

The package imports only :mod:`runtime` (and NumPy, SciPy, optionally shapely, Pillow, tifffile); the
planner and the feedback receive arrays (free-cell masks), not Domain objects.
"""
from .builtin import BUILTIN_DOMAINS
from .cells import cell_fractions
from .common import MissingExtra
from .domain import Domain
from .geodesic import GeodesicGrid, geodesic_graph, spread_kernel
from .spectrum import neumann_laplacian, neumann_modes
from .loaders import ExtentMismatch, check_source, load_domain, make_domain
from .settings import DomainSettings

__all__ = ["Domain", "DomainSettings", "BUILTIN_DOMAINS", "load_domain", "make_domain", "check_source", "MissingExtra",
           "ExtentMismatch",
           "cell_fractions", "geodesic_graph", "GeodesicGrid", "spread_kernel", "neumann_laplacian", "neumann_modes"]
