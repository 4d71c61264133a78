"""The rover FMU: building it from source, running it (:class:`FmuRunner`), terrain files.

>>> from idefix_rules.fmu import FmuRunner, default_fmu_path, synthetic_terrain, write_terrain
"""

from idefix_rules.fmu.archive import extract_fmu
from idefix_rules.fmu.build import build_fmu, default_fmu_path, source_dir
from idefix_rules.fmu.runner import FmuRunner
from idefix_rules.fmu.terrain import (
    Rock,
    Terrain,
    flat_terrain,
    load_dem,
    read_terrain,
    synthetic_terrain,
    write_terrain,
)

__all__ = [
    "FmuRunner",
    "Rock",
    "Terrain",
    "build_fmu",
    "default_fmu_path",
    "extract_fmu",
    "flat_terrain",
    "load_dem",
    "read_terrain",
    "source_dir",
    "synthetic_terrain",
    "write_terrain",
]
