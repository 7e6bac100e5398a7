"""The JSON schema of objects on the table (pydantic), shared by the REST API's request bodies and
:func:`softsig_service.objects.object_from_json`: one definition of every key, type and range.

Units and frames: lengths [m] in the object frame, ``pose`` in the world frame (``base_link``): centre (x, y)
[m], ``yaw`` [rad] about world z, optional centre height ``z`` [m]; mass [kg]; friction dimensionless. Bodies are
strict: unknown keys, NaN and infinities are errors, and numbers must be JSON numbers (``"0.5"`` and ``false``
are not). An integer is any JSON number without a fractional part, as JSON Schema counts them (``2.0`` is 2,
``2.5`` is refused).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, TypeAdapter

from softsig_service.objects.checks import MAX_ANGLE
from softsig_service.objects.cloud import MAX_POINTS


def _integral(value: Any) -> Any:
    """A float with no fractional part as the int it is (JSON Schema's integer); anything else unchanged."""
    if type(value) is float and value.is_integer():
        return int(value)
    return value


Integer = Annotated[int, BeforeValidator(_integral)]
"""An integer of a request body: a JSON number without a fractional part (strict otherwise: no string, no
boolean, no ``2.5``); declare ``strict=True`` on its field."""

MIN_LENGTH = 1e-4
"""Smallest length of an object [m] (0.1 mm): below it MuJoCo cannot simulate the object."""
MIN_MASS = 1e-4
"""Smallest mass of an object [kg] (0.1 g)."""
Length = Annotated[float, Field(ge=MIN_LENGTH, le=5.0, strict=True, description="[m]")]
Mass = Annotated[float, Field(ge=MIN_MASS, le=1000.0, strict=True, description="[kg]")]
Coordinate = Annotated[float, Field(ge=-10.0, le=10.0, strict=True, description="[m]")]
Index = Annotated[Integer, Field(ge=0, strict=True, description="0-based vertex index")]
Angle = Annotated[float, Field(ge=-MAX_ANGLE, le=MAX_ANGLE, strict=True, description="[rad], within [-2 pi, 2 pi]")]


class Strict(BaseModel):
    """Base of request bodies: unknown fields, NaN and infinities are errors (numbers of the object schema are
    strict too: no string or boolean is taken for one)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Position(Strict):
    """A position [m] (geometry_msgs/Point)."""

    x: Coordinate
    y: Coordinate
    z: Coordinate


class Orientation(Strict):
    """A unit quaternion, geometry_msgs order (normalised when within 1e-3 of unit length)."""

    x: float = Field(ge=-1.001, le=1.001, strict=True)
    y: float = Field(ge=-1.001, le=1.001, strict=True)
    z: float = Field(ge=-1.001, le=1.001, strict=True)
    w: float = Field(ge=-1.001, le=1.001, strict=True)


class ObjectPose(Strict):
    """Placement of an object: centre (x, y) [m] in ``base_link``, ``yaw`` [rad] about world z, and optionally the
    centre height ``z`` [m] (default: resting on the table). ``orientation`` (a quaternion, instead of ``yaw``)
    turns the object's frame fully, as a mug on its side or a box on its edge: the object is then planned and
    simulated as the mesh of its turned shape (docs/objects.md)."""

    x: Coordinate = 0.5
    y: Coordinate = 0.0
    yaw: Angle = 0.0
    z: Coordinate | None = None
    orientation: Orientation | None = None


class _ObjectBase(Strict):
    mass: Mass
    friction: float = Field(1.0, gt=0.0, le=10.0, strict=True, description="sliding friction coefficient")
    name: str = Field("", max_length=64)
    pose: ObjectPose = Field(default_factory=ObjectPose)


class BoxSpec(_ObjectBase):
    """A box of full side lengths ``size`` (x, y, z) [m] in the object frame."""

    kind: Literal["box"]
    size: tuple[Length, Length, Length]


class CylinderSpec(_ObjectBase):
    """A cylinder; lying (axis = object x, default) or standing (axis = object z)."""

    kind: Literal["cylinder"]
    radius: Length
    length: Length
    orientation: Literal["lying", "standing"] = "lying"


class SphereSpec(_ObjectBase):
    """A sphere of ``radius`` [m]."""

    kind: Literal["sphere"]
    radius: Length


class EllipsoidSpec(_ObjectBase):
    """An ellipsoid of semi-axes ``radii`` (x, y, z) [m]."""

    kind: Literal["ellipsoid"]
    radii: tuple[Length, Length, Length]


class MeshSpec(_ObjectBase):
    """A triangle mesh: ``vertices`` [m] in the object frame and ``faces`` (0-based vertex indices)."""

    kind: Literal["mesh"]
    vertices: list[tuple[Coordinate, Coordinate, Coordinate]] = Field(min_length=4, max_length=100_000)
    faces: list[tuple[Index, Index, Index]] = Field(min_length=1, max_length=200_000)


FRAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_/.\-]{0,127}$"
"""Names of frames (ROS tf names: REP 105's ``base_link``, ``camera_color_optical_frame``, ...)."""
FrameId = Annotated[str, Field(pattern=FRAME_PATTERN, description="a frame's name (base_link or one of frames)")]
WORLD_FRAME = "base_link"
"""The frame every answer is in: the UR5's base (z up)."""


class PointsSpec(Strict):
    """A segmented point cloud of one object: ``points`` [m] in ``frame_id`` (``base_link``, or a frame whose pose
    the request gives in ``frames``). softsig plans and simulates its conservative solid: the convex hull of the
    points (after a statistical outlier filter, unless ``filter_outliers`` is false) and of their projection onto the
    table (docs/objects.md)."""

    kind: Literal["points"]
    points: list[tuple[Coordinate, Coordinate, Coordinate]] = Field(min_length=4, max_length=MAX_POINTS)
    frame_id: FrameId = WORLD_FRAME
    filter_outliers: bool = Field(True, strict=True, description="drop statistical outliers before the hull")
    mass: Mass
    friction: float = Field(1.0, gt=0.0, le=10.0, strict=True, description="sliding friction coefficient")
    name: str = Field("", max_length=64)


class FramePose(Strict):
    """The pose of a frame in ``base_link`` (geometry_msgs/Pose), as a robot stack's tf gives it."""

    position: Position
    orientation: Orientation


class Table(Strict):
    """The table: its top is the horizontal plane ``z = height`` [m] in ``base_link``."""

    height: Coordinate = 0.0


MAX_TABLETOP_POINTS = 640 * 480
"""Most points of a tabletop cloud: a whole VGA depth frame."""


class TabletopPick(Strict):
    """Which cluster of a tabletop is the target: ``index`` (largest first), or the one whose centroid is nearest
    ``near`` [m, base_link]; neither: the largest."""

    index: Integer | None = Field(None, ge=0, le=1000, strict=True)
    near: Position | None = None


class TabletopSpec(Strict):
    """A whole tabletop cloud (table and objects) in ``frame_id``: softsig finds the table plane (RANSAC), clusters
    what stands on it (DBSCAN), plans for the cluster ``pick`` names and keeps the others as obstacles
    (docs/objects.md). ``mass`` and ``friction`` are the target's."""

    kind: Literal["tabletop"]
    points: list[tuple[Coordinate, Coordinate, Coordinate]] = Field(min_length=20, max_length=MAX_TABLETOP_POINTS)
    frame_id: FrameId = WORLD_FRAME
    pick: TabletopPick = Field(default_factory=lambda: TabletopPick())
    plane_tolerance: float = Field(0.008, ge=0.001, le=0.05, strict=True, description="[m] table inliers")
    cluster_distance: float = Field(0.015, ge=0.002, le=0.1, strict=True, description="[m] DBSCAN radius")
    min_points: Integer = Field(50, ge=4, le=100_000, strict=True, description="smallest cluster [points]")
    filter_outliers: bool = Field(True, strict=True, description="drop statistical outliers of each cluster")
    mass: Mass
    friction: float = Field(1.0, gt=0.0, le=10.0, strict=True, description="sliding friction coefficient")
    name: str = Field("", max_length=64)


MAX_FRAMES = 64
"""Most frames a request may give."""
MAX_OBSTACLES = 32
"""Most obstacles a plan takes."""


class SceneFields(Strict):
    """What a request says of the scene besides its objects: the table and the frames its geometry may be in."""

    table: Table = Field(default_factory=Table, description="the table top (its height in base_link)")
    frames: dict[Annotated[str, Field(pattern=FRAME_PATTERN)], FramePose] = Field(
        default_factory=dict, max_length=MAX_FRAMES,
        description="poses in base_link of the frames an object's frame_id may name (tf, geometry_msgs order)",
    )  # fmt: skip


OBJECT_ID_PATTERN = r"^[0-9a-f]{32}$"
"""Ids of registered objects."""


class StoredObjectSpec(Strict):
    """An object registered with ``POST /v1/objects``, by ``id``: at the pose it was registered at, or at ``pose``;
    optionally with another ``mass`` or ``friction``. Its geometry is sent once, its collision structures are built
    once."""

    kind: Literal["stored"]
    id: str = Field(pattern=OBJECT_ID_PATTERN, description="the id POST /v1/objects answered")
    pose: ObjectPose | None = None
    mass: Mass | None = None
    friction: float | None = Field(None, gt=0.0, le=10.0, strict=True)


class BuiltinObjectSpec(Strict):
    """One of the objects of docs/design.md §7 (box, apple, cylinder) or a shipped household mesh (mug, banana,
    power_drill, mustard_bottle: softsig_service/objects/meshes/README.md), optionally with another mass, friction
    or pose."""

    kind: Literal["builtin"]
    name: Literal["box", "apple", "cylinder", "mug", "banana", "power_drill", "mustard_bottle"]
    mass: Mass | None = None
    friction: float | None = Field(None, gt=0.0, le=10.0, strict=True)
    pose: ObjectPose | None = None


ObjectSpec = Annotated[
    BoxSpec
    | CylinderSpec
    | SphereSpec
    | EllipsoidSpec
    | MeshSpec
    | PointsSpec
    | TabletopSpec
    | StoredObjectSpec
    | BuiltinObjectSpec,
    Field(discriminator="kind"),
]
UNION_TAGS: frozenset[str] = frozenset(
    {"box", "cylinder", "sphere", "ellipsoid", "mesh", "points", "tabletop", "stored", "builtin"}
)
"""Discriminator values: pydantic puts them in error locations; field paths leave them out."""


OBJECT_SPEC: TypeAdapter[Any] = TypeAdapter(ObjectSpec)
"""Validates an object JSON against :data:`ObjectSpec`."""


def object_json(spec: BaseModel) -> dict[str, Any]:
    """The object JSON of an :data:`ObjectSpec` (unset optional keys left out)."""
    return spec.model_dump(exclude_none=True)
