"""Obstacle risk: rover bodies and obstacles as python-fcl geometry, checked along every run.

>>> from idefix_rules.obstacles import ObstacleSet, RoverBodies, collision_signals
"""

from idefix_rules.obstacles.areas import polygon_area, steep_terrain, unknown_terrain
from idefix_rules.obstacles.bodies import PARTS, Body, RoverBodies, rotation_matrices
from idefix_rules.obstacles.check import collision_signals
from idefix_rules.obstacles.obstacles import (
    LEVELS,
    LevelThresholds,
    Obstacle,
    ObstacleSet,
    Piece,
    level_index,
)
from idefix_rules.obstacles.result import (
    CheckSettings,
    CollisionResult,
    FirstContact,
    RunCollisions,
)

__all__ = [
    "LEVELS",
    "PARTS",
    "Body",
    "CheckSettings",
    "CollisionResult",
    "FirstContact",
    "LevelThresholds",
    "Obstacle",
    "ObstacleSet",
    "Piece",
    "RoverBodies",
    "RunCollisions",
    "collision_signals",
    "level_index",
    "polygon_area",
    "rotation_matrices",
    "steep_terrain",
    "unknown_terrain",
]
