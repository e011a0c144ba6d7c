"""Domain geometry: the free space and obstacles inside the rectangle Omega, at the geometry's own resolution."""
from .domain import (BUILTIN_DOMAINS, Domain, DomainSettings, GeodesicGrid, MissingExtra, cell_fractions,
                     geodesic_graph, load_domain, make_domain)

__all__ = ["Domain", "DomainSettings", "BUILTIN_DOMAINS", "load_domain", "make_domain", "MissingExtra",
           "cell_fractions", "geodesic_graph", "GeodesicGrid"]
