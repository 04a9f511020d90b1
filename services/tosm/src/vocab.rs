//! IRIs of every class, property and individual of the TOSM ontology (`ontologies/tosm.ttl`),
//! as `oxrdf` constants, plus the namespaces the data lives under.
//!
//! A test checks that this list and the ontology file name exactly the same terms.

use oxrdf::NamedNodeRef;

/// The ontology's namespace; every term IRI is this followed by the term's name.
pub const NS: &str = "https://mentalsim.dev/ontology/tosm#";
/// The ontology's own IRI.
pub const ONTOLOGY: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("https://mentalsim.dev/ontology/tosm");
/// Where instance data lives: buildings under `data/buildings/`, robots under `data/robots/`.
pub const DATA_NS: &str = "https://mentalsim.dev/data/";

macro_rules! terms {
    ($($(#[$doc:meta])* $name:ident = $local:literal,)*) => {
        $(
            $(#[$doc])*
            pub const $name: NamedNodeRef<'static> =
                NamedNodeRef::new_unchecked(concat!("https://mentalsim.dev/ontology/tosm#", $local));
        )*
        /// Every term above, with its local name, in the ontology file's order.
        pub const ALL: &[(&str, NamedNodeRef<'static>)] = &[$(($local, $name),)*];
    };
}

terms! {
    /// `tosm:belongsToModel` (annotation property).
    BELONGS_TO_MODEL = "belongsToModel",
    /// `tosm:Entity` (class).
    ENTITY = "Entity",
    /// `tosm:Descriptor` (class).
    DESCRIPTOR = "Descriptor",
    /// `tosm:Place` (class).
    PLACE = "Place",
    /// `tosm:Building` (class).
    BUILDING = "Building",
    /// `tosm:Floor` (class).
    FLOOR = "Floor",
    /// `tosm:Corridor` (class).
    CORRIDOR = "Corridor",
    /// `tosm:Room` (class).
    ROOM = "Room",
    /// `tosm:Hall` (class).
    HALL = "Hall",
    /// `tosm:Object` (class).
    OBJECT = "Object",
    /// `tosm:Door` (class).
    DOOR = "Door",
    /// `tosm:Table` (class).
    TABLE = "Table",
    /// `tosm:Chair` (class).
    CHAIR = "Chair",
    /// `tosm:Shelf` (class).
    SHELF = "Shelf",
    /// `tosm:Cabinet` (class).
    CABINET = "Cabinet",
    /// `tosm:Sofa` (class).
    SOFA = "Sofa",
    /// `tosm:Bin` (class).
    BIN = "Bin",
    /// `tosm:VendingMachine` (class).
    VENDING_MACHINE = "VendingMachine",
    /// `tosm:Robot` (class).
    ROBOT = "Robot",
    /// `tosm:DifferentialDriveRobot` (class).
    DIFFERENTIAL_DRIVE_ROBOT = "DifferentialDriveRobot",
    /// `tosm:RobotPart` (class).
    ROBOT_PART = "RobotPart",
    /// `tosm:StructuralPart` (class).
    STRUCTURAL_PART = "StructuralPart",
    /// `tosm:Wheel` (class).
    WHEEL = "Wheel",
    /// `tosm:ActiveWheel` (class).
    ACTIVE_WHEEL = "ActiveWheel",
    /// `tosm:PassiveWheel` (class).
    PASSIVE_WHEEL = "PassiveWheel",
    /// `tosm:CasterWheel` (class).
    CASTER_WHEEL = "CasterWheel",
    /// `tosm:Joint` (class).
    JOINT = "Joint",
    /// `tosm:FixedJoint` (class).
    FIXED_JOINT = "FixedJoint",
    /// `tosm:ContinuousJoint` (class).
    CONTINUOUS_JOINT = "ContinuousJoint",
    /// `tosm:Sensor` (class).
    SENSOR = "Sensor",
    /// `tosm:Camera` (class).
    CAMERA = "Camera",
    /// `tosm:StereoCamera` (class).
    STEREO_CAMERA = "StereoCamera",
    /// `tosm:RGBDCamera` (class).
    RGBD_CAMERA = "RGBDCamera",
    /// `tosm:LaserRangeFinder` (class).
    LASER_RANGE_FINDER = "LaserRangeFinder",
    /// `tosm:Pose` (class).
    POSE = "Pose",
    /// `tosm:Shape` (class).
    SHAPE = "Shape",
    /// `tosm:BoxShape` (class).
    BOX_SHAPE = "BoxShape",
    /// `tosm:CylinderShape` (class).
    CYLINDER_SHAPE = "CylinderShape",
    /// `tosm:SphereShape` (class).
    SPHERE_SHAPE = "SphereShape",
    /// `tosm:BoundaryPoint` (class).
    BOUNDARY_POINT = "BoundaryPoint",
    /// `tosm:MetricMap` (class).
    METRIC_MAP = "MetricMap",
    /// `tosm:OccupancyGridMap` (class).
    OCCUPANCY_GRID_MAP = "OccupancyGridMap",
    /// `tosm:Material` (class).
    MATERIAL = "Material",
    /// `tosm:WalkingRoute` (class).
    WALKING_ROUTE = "WalkingRoute",
    /// `tosm:Attractor` (class).
    ATTRACTOR = "Attractor",
    /// `tosm:RoutePoint` (class).
    ROUTE_POINT = "RoutePoint",
    /// `tosm:HourlyPeopleCount` (class).
    HOURLY_PEOPLE_COUNT = "HourlyPeopleCount",
    /// `tosm:PeopleEstimate` (class).
    PEOPLE_ESTIMATE = "PeopleEstimate",
    /// `tosm:Wood` (individual).
    WOOD = "Wood",
    /// `tosm:Steel` (individual).
    STEEL = "Steel",
    /// `tosm:Aluminium` (individual).
    ALUMINIUM = "Aluminium",
    /// `tosm:Plastic` (individual).
    PLASTIC = "Plastic",
    /// `tosm:Rubber` (individual).
    RUBBER = "Rubber",
    /// `tosm:Glass` (individual).
    GLASS = "Glass",
    /// `tosm:Fabric` (individual).
    FABRIC = "Fabric",
    /// `tosm:Concrete` (individual).
    CONCRETE = "Concrete",
    /// `tosm:Cardboard` (individual).
    CARDBOARD = "Cardboard",
    /// `tosm:ExplicitModel` (individual).
    EXPLICIT_MODEL = "ExplicitModel",
    /// `tosm:ImplicitModel` (individual).
    IMPLICIT_MODEL = "ImplicitModel",
    /// `tosm:SymbolicModel` (individual).
    SYMBOLIC_MODEL = "SymbolicModel",
    /// `tosm:hasPose` (object property).
    HAS_POSE = "hasPose",
    /// `tosm:hasMountingPose` (object property).
    HAS_MOUNTING_POSE = "hasMountingPose",
    /// `tosm:hasShape` (object property).
    HAS_SHAPE = "hasShape",
    /// `tosm:hasBoundaryPoint` (object property).
    HAS_BOUNDARY_POINT = "hasBoundaryPoint",
    /// `tosm:hasMetricMap` (object property).
    HAS_METRIC_MAP = "hasMetricMap",
    /// `tosm:hasMaterial` (object property).
    HAS_MATERIAL = "hasMaterial",
    /// `tosm:isInsideOf` (object property).
    IS_INSIDE_OF = "isInsideOf",
    /// `tosm:contains` (object property).
    CONTAINS = "contains",
    /// `tosm:isDirectlyInsideOf` (object property).
    IS_DIRECTLY_INSIDE_OF = "isDirectlyInsideOf",
    /// `tosm:directlyContains` (object property).
    DIRECTLY_CONTAINS = "directlyContains",
    /// `tosm:isConnectedTo` (object property).
    IS_CONNECTED_TO = "isConnectedTo",
    /// `tosm:isNextTo` (object property).
    IS_NEXT_TO = "isNextTo",
    /// `tosm:isInFrontOf` (object property).
    IS_IN_FRONT_OF = "isInFrontOf",
    /// `tosm:connectsPlace` (object property).
    CONNECTS_PLACE = "connectsPlace",
    /// `tosm:hasRoutePoint` (object property).
    HAS_ROUTE_POINT = "hasRoutePoint",
    /// `tosm:hasHourlyPeopleCount` (object property).
    HAS_HOURLY_PEOPLE_COUNT = "hasHourlyPeopleCount",
    /// `tosm:hasPeopleEstimate` (object property).
    HAS_PEOPLE_ESTIMATE = "hasPeopleEstimate",
    /// `tosm:reportedBy` (object property).
    REPORTED_BY = "reportedBy",
    /// `tosm:hasPart` (object property).
    HAS_PART = "hasPart",
    /// `tosm:hasBasePart` (object property).
    HAS_BASE_PART = "hasBasePart",
    /// `tosm:hasSensor` (object property).
    HAS_SENSOR = "hasSensor",
    /// `tosm:hasParentPart` (object property).
    HAS_PARENT_PART = "hasParentPart",
    /// `tosm:hasChildPart` (object property).
    HAS_CHILD_PART = "hasChildPart",
    /// `tosm:xM` (datatype property).
    X_M = "xM",
    /// `tosm:yM` (datatype property).
    Y_M = "yM",
    /// `tosm:zM` (datatype property).
    Z_M = "zM",
    /// `tosm:rollRad` (datatype property).
    ROLL_RAD = "rollRad",
    /// `tosm:pitchRad` (datatype property).
    PITCH_RAD = "pitchRad",
    /// `tosm:yawRad` (datatype property).
    YAW_RAD = "yawRad",
    /// `tosm:pointIndex` (datatype property).
    POINT_INDEX = "pointIndex",
    /// `tosm:lengthM` (datatype property).
    LENGTH_M = "lengthM",
    /// `tosm:widthM` (datatype property).
    WIDTH_M = "widthM",
    /// `tosm:heightM` (datatype property).
    HEIGHT_M = "heightM",
    /// `tosm:colourRed` (datatype property).
    COLOUR_RED = "colourRed",
    /// `tosm:colourGreen` (datatype property).
    COLOUR_GREEN = "colourGreen",
    /// `tosm:colourBlue` (datatype property).
    COLOUR_BLUE = "colourBlue",
    /// `tosm:colourAlpha` (datatype property).
    COLOUR_ALPHA = "colourAlpha",
    /// `tosm:mapImagePng` (datatype property).
    MAP_IMAGE_PNG = "mapImagePng",
    /// `tosm:resolutionM` (datatype property).
    RESOLUTION_M = "resolutionM",
    /// `tosm:originXM` (datatype property).
    ORIGIN_X_M = "originXM",
    /// `tosm:originYM` (datatype property).
    ORIGIN_Y_M = "originYM",
    /// `tosm:originYawRad` (datatype property).
    ORIGIN_YAW_RAD = "originYawRad",
    /// `tosm:occupiedThreshold` (datatype property).
    OCCUPIED_THRESHOLD = "occupiedThreshold",
    /// `tosm:freeThreshold` (datatype property).
    FREE_THRESHOLD = "freeThreshold",
    /// `tosm:negate` (datatype property).
    NEGATE = "negate",
    /// `tosm:frameId` (datatype property).
    FRAME_ID = "frameId",
    /// `tosm:widthCells` (datatype property).
    WIDTH_CELLS = "widthCells",
    /// `tosm:heightCells` (datatype property).
    HEIGHT_CELLS = "heightCells",
    /// `tosm:massKg` (datatype property).
    MASS_KG = "massKg",
    /// `tosm:frictionCoefficient` (datatype property).
    FRICTION_COEFFICIENT = "frictionCoefficient",
    /// `tosm:complexity` (datatype property).
    COMPLEXITY = "complexity",
    /// `tosm:floorLevel` (datatype property).
    FLOOR_LEVEL = "floorLevel",
    /// `tosm:isOpen` (datatype property).
    IS_OPEN = "isOpen",
    /// `tosm:reportedAt` (datatype property).
    REPORTED_AT = "reportedAt",
    /// `tosm:expectedPeople` (datatype property).
    EXPECTED_PEOPLE = "expectedPeople",
    /// `tosm:hourOfDay` (datatype property).
    HOUR_OF_DAY = "hourOfDay",
    /// `tosm:estimatedPeople` (datatype property).
    ESTIMATED_PEOPLE = "estimatedPeople",
    /// `tosm:observationCount` (datatype property).
    OBSERVATION_COUNT = "observationCount",
    /// `tosm:lastObservedAt` (datatype property).
    LAST_OBSERVED_AT = "lastObservedAt",
    /// `tosm:dwellTimeS` (datatype property).
    DWELL_TIME_S = "dwellTimeS",
    /// `tosm:wheelRadiusM` (datatype property).
    WHEEL_RADIUS_M = "wheelRadiusM",
    /// `tosm:wheelWidthM` (datatype property).
    WHEEL_WIDTH_M = "wheelWidthM",
    /// `tosm:axisX` (datatype property).
    AXIS_X = "axisX",
    /// `tosm:axisY` (datatype property).
    AXIS_Y = "axisY",
    /// `tosm:axisZ` (datatype property).
    AXIS_Z = "axisZ",
    /// `tosm:imageWidthPx` (datatype property).
    IMAGE_WIDTH_PX = "imageWidthPx",
    /// `tosm:imageHeightPx` (datatype property).
    IMAGE_HEIGHT_PX = "imageHeightPx",
    /// `tosm:frameRateHz` (datatype property).
    FRAME_RATE_HZ = "frameRateHz",
    /// `tosm:horizontalFovRad` (datatype property).
    HORIZONTAL_FOV_RAD = "horizontalFovRad",
    /// `tosm:verticalFovRad` (datatype property).
    VERTICAL_FOV_RAD = "verticalFovRad",
    /// `tosm:baselineM` (datatype property).
    BASELINE_M = "baselineM",
    /// `tosm:rangeMinM` (datatype property).
    RANGE_MIN_M = "rangeMinM",
    /// `tosm:rangeMaxM` (datatype property).
    RANGE_MAX_M = "rangeMaxM",
    /// `tosm:viewAngleRad` (datatype property).
    VIEW_ANGLE_RAD = "viewAngleRad",
    /// `tosm:sampleCount` (datatype property).
    SAMPLE_COUNT = "sampleCount",
    /// `tosm:angularResolutionRad` (datatype property).
    ANGULAR_RESOLUTION_RAD = "angularResolutionRad",
    /// `tosm:maxLinearSpeedMPerS` (datatype property).
    MAX_LINEAR_SPEED_M_PER_S = "maxLinearSpeedMPerS",
    /// `tosm:maxAngularSpeedRadPerS` (datatype property).
    MAX_ANGULAR_SPEED_RAD_PER_S = "maxAngularSpeedRadPerS",
    /// `tosm:maxLinearAccelerationMPerS2` (datatype property).
    MAX_LINEAR_ACCELERATION_M_PER_S2 = "maxLinearAccelerationMPerS2",
    /// `tosm:maxLinearDecelerationMPerS2` (datatype property).
    MAX_LINEAR_DECELERATION_M_PER_S2 = "maxLinearDecelerationMPerS2",
    /// `tosm:maxAngularAccelerationRadPerS2` (datatype property).
    MAX_ANGULAR_ACCELERATION_RAD_PER_S2 = "maxAngularAccelerationRadPerS2",
    /// `tosm:maxAngularDecelerationRadPerS2` (datatype property).
    MAX_ANGULAR_DECELERATION_RAD_PER_S2 = "maxAngularDecelerationRadPerS2",
    /// `tosm:controlLatencyS` (datatype property).
    CONTROL_LATENCY_S = "controlLatencyS",
    /// `tosm:name` (datatype property).
    NAME = "name",
    /// `tosm:identifier` (datatype property).
    IDENTIFIER = "identifier",
    /// `tosm:description` (datatype property).
    DESCRIPTION = "description",
    /// `tosm:colourName` (datatype property).
    COLOUR_NAME = "colourName",
}
