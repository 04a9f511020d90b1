"""A typed Python client of Mentalsim, the cloud service where robots rehearse their plans in a
mental simulation before they move.

>>> from mentalsim_client import Client
>>> with Client("http://127.0.0.1:8080", token) as client:          # doctest: +SKIP
...     plan = client.plan("R-001", "F0", start=(-9.5, 2.0, 0.0), goal=(-15.0, 0.0))
...     print(plan.path.points())
"""

from ._operations import OPERATIONS, Operation
from .client import Client, OnDemandDatabase, RdfFormat, Waypoint, __version__
from .errors import MentalsimError
from .models import (
    AttemptReport,
    Box,
    Colour,
    Cylinder,
    ImportedMap,
    Job,
    JobEvent,
    JobKind,
    JobState,
    LegReport,
    MapInfo,
    Me,
    Place,
    PlanOptions,
    PlanResult,
    Point,
    PolicySummary,
    Pose,
    ReportedObject,
    ResponseShapeError,
    Roadmap,
    RoadmapEdge,
    RoadmapInfo,
    Robot,
    RosPath,
    RosPoseStamped,
    Shape,
    Sphere,
    WorldObject,
)
from .policy import Action, Observation, Policy, PolicyError, Residual, Scaling, load_policy

__all__ = [
    "OPERATIONS",
    "Action",
    "AttemptReport",
    "Box",
    "Client",
    "Colour",
    "Cylinder",
    "ImportedMap",
    "Job",
    "JobEvent",
    "JobKind",
    "JobState",
    "LegReport",
    "MapInfo",
    "Me",
    "MentalsimError",
    "Observation",
    "OnDemandDatabase",
    "Operation",
    "Place",
    "PlanOptions",
    "PlanResult",
    "Point",
    "Policy",
    "PolicyError",
    "PolicySummary",
    "Pose",
    "RdfFormat",
    "ReportedObject",
    "Residual",
    "ResponseShapeError",
    "Roadmap",
    "RoadmapEdge",
    "RoadmapInfo",
    "Robot",
    "RosPath",
    "RosPoseStamped",
    "Scaling",
    "Shape",
    "Sphere",
    "Waypoint",
    "WorldObject",
    "__version__",
    "load_policy",
]
