"""Simulated X-ray projections (DRRs) of CT volumes: exact Siddon and trilinear ray tracing.

The compiled core (volumes, geometry, projections, phantoms, detector physics, scatter) is
re-exported here from ``tomograf._native``; ``tomograf.distributed`` deals the command
line's sharded jobs out to a Ray cluster (``pip install ./bridge[ray]``). Units: mm,
mm⁻¹, keV, HU, degrees; world frame DICOM LPS. See docs/python.md.
"""

from ._native import *  # noqa: F401,F403 — the public API is the compiled module's
from ._native import __doc__, __version__  # noqa: F401
